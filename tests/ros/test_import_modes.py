"""Imported system_modes models run by a real manager: the drone's three levels
(fixtures/system_modes/drone.yaml) reach real rclpy lifecycle nodes' parameters and states,
and the rover's rule (rover.yaml) reacts to a node another client deactivates."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import GetParameters

from contextros.language.system_modes import import_modes
from contextros.ros import LayerClient
from tests.language.conftest import FIXTURES
from tests.ros.processes import HERE, ProcessGroup
from tests.ros.system import LIVENESS, wait_registry
from tests.ros.test_ros_bindings import call

# The models' nodes with their values before any mode (none of the models').
NODES: dict[str, dict[str, Any]] = {
    "motors/front": {"rpm": -1, "spin": "unset"},
    "motors/rear": {"rpm": -1, "spin": "unset"},
    "camera": {"resolution": 1, "stream": False},
    "arm": {"max_torque": 0.0},
    "base": {"max_speed": 0.0, "planner": "none", "limits.reverse": False},
}
DRONE = ["motors/front", "motors/rear", "camera"]


@pytest.fixture(scope="module")
def drone(client: LayerClient, tmp_path_factory: pytest.TempPathFactory) -> Iterator[ProcessGroup]:
    folder = tmp_path_factory.mktemp("modes")
    layers = []
    for name in ("drone", "rover"):
        model = (FIXTURES / "system_modes" / f"{name}.yaml").read_text(encoding="utf-8")
        layers.append(str(folder / f"{name}.layers"))
        Path(layers[-1]).write_text(import_modes(model, f"{name}.yaml").text, encoding="utf-8")
    group = ProcessGroup()
    try:
        script = str(HERE / "modes_nodes_process.py")
        nodes = group.start("model nodes", [script, json.dumps(NODES), *layers])
        group.manager("--liveness-timeout", LIVENESS, "--layers", *layers)
        nodes.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
        client.wait_for_manager(15.0)
        wait_registry(
            client,
            lambda r: any(p.node == "/modes_participant" for p in r.participants),
            show=group.children,
        )
        yield group
    finally:
        group.kill_all()


def parameters(client: LayerClient, node: str) -> dict[str, Any]:
    names = list(NODES[node])
    response = call(
        client, GetParameters, f"/{node}/get_parameters", GetParameters.Request(names=names)
    )
    found: dict[str, Any] = {}
    for name, value in zip(names, response.values, strict=True):
        found[name] = {
            1: value.bool_value,
            2: value.integer_value,
            3: value.double_value,
            4: value.string_value,
        }.get(value.type)
    return found


def state(client: LayerClient, node: str) -> str:
    return str(call(client, GetState, f"/{node}/get_state", GetState.Request()).current_state.label)


def test_a_system_mode_sets_its_parts_modes_three_levels_down(
    drone: ProcessGroup, client: LayerClient
) -> None:
    result = client.request(["drone_FLIGHT"], synchronous=True, timeout=10)
    assert result.success, result.message
    active = set(client.query().active_layers)
    assert {"drone_FLIGHT", "propulsion_ON", "motors_front_RUN", "camera_HIGH_RES"} <= active
    assert parameters(client, "motors/front") == {"rpm": 4200, "spin": "clockwise"}
    assert parameters(client, "motors/rear") == {"rpm": 4000, "spin": "counterclockwise"}
    assert parameters(client, "camera") == {"resolution": 2160, "stream": True}
    assert [state(client, node) for node in DRONE] == ["active", "active", "active"]

    # The system's __DEFAULT__: propulsion inactive (both motors), the camera in its default.
    result = client.request(["drone_DEFAULT"], synchronous=True, timeout=10)
    assert result.success, result.message
    active = set(client.query().active_layers)
    assert "propulsion_ON" not in active and "motors_front_RUN" not in active
    assert {"drone_DEFAULT", "camera_DEFAULT"} <= active
    assert [state(client, node) for node in DRONE] == ["inactive", "inactive", "active"]
    assert parameters(client, "camera") == {"resolution": 480, "stream": False}

    # No mode at all: every value and state from before the first mode comes back.
    result = client.request((), ["drone_DEFAULT"], synchronous=True, timeout=10)
    assert result.success, result.message
    assert parameters(client, "motors/front") == NODES["motors/front"]
    assert parameters(client, "camera") == NODES["camera"]


def test_a_rule_of_the_model_reacts_to_a_part_another_client_deactivates(
    drone: ProcessGroup, client: LayerClient
) -> None:
    result = client.request(["rover_RUSH"], synchronous=True, timeout=10)
    assert result.success, result.message
    assert {"rover_RUSH", "arm_FIRM", "base_SPRINT"} <= set(client.query().active_layers)
    assert parameters(client, "base")["max_speed"] == 2.5, "\n".join(
        c.output() for c in drone.children
    )
    assert state(client, "base") == "active", "\n".join(c.output() for c in drone.children)
    # Someone else takes the base down: the model's rule stop_if_base_fails (rover.yaml:24)
    # deactivates the system's mode, and with it the part modes it implied.
    change = ChangeState.Request()
    change.transition.id = Transition.TRANSITION_DEACTIVATE
    assert call(client, ChangeState, "/base/change_state", change).success
    wait_registry(
        client,
        lambda r: "rover_RUSH" not in r.active_layers and "base_SPRINT" not in r.active_layers,
        what="rule stop_if_base_fails",
        show=drone.children,
    )
    assert parameters(client, "base")["max_speed"] == NODES["base"]["max_speed"]
