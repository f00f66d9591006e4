"""A manager whose layer files only bind parameters and lifecycle states, with no context
node at all: the files' layers are its own (declared by the manager), a synchronous switch
is applied by 0 nodes and succeeds once their ROS side is, and the import-modes example of
docs/ros-integration.md runs as documented."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import HERE, ProcessGroup
from tests.ros.system import LIVENESS
from tests.ros.test_cli import contextros
from tests.ros.test_import_modes import NODES, parameters, state
from tests.ros.test_ros_bindings import max_speed, propeller_state

BINDINGS_ONLY = """\
parameter Slow: base max_speed = 0.3
lifecycle Outdoor: propeller active
"""

DOCS = Path(__file__).parents[2] / "docs" / "ros-integration.md"


def started(group: ProcessGroup, client: LayerClient, nodes: list[str], layers: Path) -> None:
    plain = group.start("plain nodes", nodes)
    group.manager("--liveness-timeout", LIVENESS, "--layers", str(layers))
    plain.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    client.wait_for_manager(15.0)


@pytest.fixture
def group() -> Iterator[ProcessGroup]:
    group = ProcessGroup()
    try:
        yield group
    finally:
        group.kill_all()


def test_a_bindings_only_layer_file_switches_with_no_context_node(
    group: ProcessGroup, client: LayerClient, tmp_path: Path
) -> None:
    layers = tmp_path / "robot.layers"
    layers.write_text(BINDINGS_ONLY, encoding="utf-8")
    started(group, client, [str(HERE / "plain_nodes_process.py")], layers)
    shown = "\n".join(c.output() for c in group.children)

    done = contextros("activate", "Slow", "Outdoor", "--sync", "--timeout", "10", "--json")
    assert done.returncode == 0, done.stdout + done.stderr + shown
    answer = json.loads(done.stdout)
    assert "applied by 0 node(s)" in answer["message"] and answer["acknowledged"] == []
    assert max_speed(client) == pytest.approx(0.3)
    assert propeller_state(client) == "active"

    status = json.loads(contextros("status", "--json").stdout)
    slow = next(layer for layer in status["layers"] if layer["name"] == "Slow")
    assert slow["implemented_by"] == [] and slow["declared_by_manager"]
    assert "declared by the manager's layer file" in contextros("status").stdout

    done = contextros("deactivate", "Slow", "--sync", "--timeout", "10")
    assert done.returncode == 0, done.stdout + done.stderr
    assert max_speed(client) == pytest.approx(1.0)  # the value from before the layer


def test_the_import_modes_example_of_the_docs_runs_with_no_context_node(
    group: ProcessGroup, client: LayerClient, tmp_path: Path
) -> None:
    found = re.search(r"<!-- import-modes: model -->\n```yaml\n(.*?)```", DOCS.read_text(), re.S)
    assert found, "the import-modes example left docs/ros-integration.md"
    model = tmp_path / "rover_modes.yaml"
    model.write_text(found.group(1), encoding="utf-8")
    layers = tmp_path / "rover.layers"
    done = contextros("import-modes", str(model), "-o", str(layers))
    assert done.returncode == 0, done.stderr
    nodes = {"arm": NODES["arm"], "base": NODES["base"]}
    started(group, client, [str(HERE / "modes_nodes_process.py"), json.dumps(nodes)], layers)

    done = contextros("activate", "rover_RUSH", "--sync", "--timeout", "10")
    shown = "\n".join(c.output() for c in group.children)
    assert done.returncode == 0, done.stdout + done.stderr + shown
    assert {"rover_RUSH", "arm_FIRM", "base_FAST"} <= set(client.query().active_layers)
    assert parameters(client, "arm") == {"max_torque": 2.0}
    assert parameters(client, "base") == {**NODES["base"], "max_speed": 2.5, "planner": "DWB"}
    assert [state(client, "arm"), state(client, "base")] == ["active", "active"]
