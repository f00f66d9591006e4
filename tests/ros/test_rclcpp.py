"""rclcpp nodes following the Layer manager beside a Python node (`make test-rclcpp`): an
rclcpp::Node through `follow_manager(*this)`, an rclcpp_lifecycle::LifecycleNode driven by a
lifecycle binding, and two components in one rclcpp_components container.

The programs are cpp/ros/tests/rclcpp/, built against rclcpp by `make test-rclcpp` (from the
vendored sources, or a system ROS 2's); it sets CONTEXTROS_RCLCPP_BUILD (the C++ build) and
CONTEXTROS_RCLCPP_PREFIX (where rclcpp is). Without them (`make test`) the module is
skipped: rclcpp is no wheel, and building it takes minutes.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import start_system, wait_registry

if not os.environ.get("CONTEXTROS_RCLCPP_BUILD"):
    pytest.skip("rclcpp's tests run with `make test-rclcpp`", allow_module_level=True)

BUILD = Path(os.environ["CONTEXTROS_RCLCPP_BUILD"]) / "ros/tests/rclcpp"
PREFIX = Path(os.environ["CONTEXTROS_RCLCPP_PREFIX"])
PROTOCOL_TOPICS = ("state", "heartbeat", "proposal", "status")


def program(name: str) -> str:
    path = BUILD / f"contextros_test_{name}"
    assert path.exists(), f"{path} is not built (make test-rclcpp builds it)"
    return str(path)


def start(processes: ProcessGroup, name: str, executable: str, *argv: str) -> Child:
    # The container finds the test components in the build's ament index, and the
    # typesupport of rclcpp's own messages in its prefix's.
    ament = os.pathsep.join(
        [str(BUILD / "ament"), str(PREFIX), os.environ.get("AMENT_PREFIX_PATH", "")]
    )
    child = Child(name, list(argv), env={"AMENT_PREFIX_PATH": ament}, program=executable)
    processes.children.append(child)
    return child


def ready(child: Child) -> dict[str, Any]:
    return child.wait_for(
        lambda events: next((e for e in events if e["event"] == "ready"), None), 15, "ready"
    )


def transitions_before(node: Child, epoch: int) -> list[str]:
    """The lifecycle transitions the node printed before it applied `epoch` (its output is
    in the order things happened in it)."""
    applied = node.wait_applied(epoch)
    events = node.events[: node.events.index(applied)]
    return [e["transition"] for e in events if e["event"] == "transition"]


def registered(client: LayerClient, *nodes: str) -> Any:
    return wait_registry(
        client,
        lambda r: (
            {p.node for p in r.participants} >= set(nodes)
            and all(p.applied_epoch == r.epoch for p in r.participants)
        ),
        what=f"{nodes} on the current state",
    )


def test_an_rclcpp_node_follows_the_manager_beside_a_python_node(
    client: LayerClient, processes: ProcessGroup
) -> None:
    node = start(processes, "rclcpp node", program("rclcpp_node"), "--name", "rc")
    assert ready(node)["rclcpp"] == "29.3.0"
    system = start_system(processes, client, ["py"])
    registered(client, "/rc", "/py")

    synchronous = client.request(["Indoor", "Night"], synchronous=True, timeout=5)
    assert synchronous.success, synchronous.message
    assert synchronous.acknowledged == ("/py", "/rc")
    for child in (node, system.participants["py"]):
        applied = child.wait_applied(synchronous.epoch, timeout=2)
        assert applied["mode"] == "quiet+wipe+base", child.name
    # What the node's own executor sees (a wall timer calling the layered function).
    node.wait_for(
        lambda events: any(e == {"event": "mode", "mode": "quiet+wipe+base"} for e in events),
        5,
        "the timer's view",
    )

    atomic = client.request(["Outdoor"], atomic=True, timeout=5)
    assert atomic.success, atomic.message
    assert atomic.acknowledged == ("/py", "/rc")
    assert node.wait_applied(atomic.epoch)["mode"] == "vacuum+quiet+base"

    refused = client.request(["Slow", "Fast"], synchronous=True, timeout=5)
    assert not refused.success and "Slow excludes Fast" in refused.message, refused.message
    assert refused.epoch == atomic.epoch

    node.signal(signal.SIGKILL)
    killed = time.monotonic()
    wait_registry(client, lambda r: "/rc" not in {p.node for p in r.participants}, 5, "/rc dropped")
    assert time.monotonic() - killed < 3.0, "a killed rclcpp node is dropped within 3 s"


def test_an_rclcpp_nodes_veto_aborts_an_atomic_activation(
    client: LayerClient, processes: ProcessGroup
) -> None:
    node = start(
        processes,
        "vetoing rclcpp node",
        program("rclcpp_node"),
        "--name",
        "rc",
        "--veto",
        "docking",
    )
    ready(node)
    start_system(processes, client, ["py"])
    before = registered(client, "/rc", "/py").epoch
    started = time.monotonic()
    vetoed = client.request(["Night"], atomic=True, timeout=5)
    assert time.monotonic() - started < 2.0, "a veto is answered at once"
    assert not vetoed.success and vetoed.not_acknowledged == ("/rc",), vetoed.message
    assert "/rc vetoed: docking" in vetoed.message, vetoed.message
    assert client.query().epoch == before, "nothing changed anywhere"
    # Not atomic: no vote, and the node applies it.
    applied = client.request(["Night"], synchronous=True, timeout=5)
    assert applied.success and applied.acknowledged == ("/py", "/rc"), applied.message


def test_an_rclcpp_node_leaves_at_once_when_rclcpp_shuts_down(
    client: LayerClient, processes: ProcessGroup
) -> None:
    node = start(processes, "rclcpp node", program("rclcpp_node"), "--name", "rc")
    ready(node)
    # A long liveness bound: only the node's leaving report can drop it quickly.
    system = start_system(processes, client, ["py"], "--liveness-timeout", "30")
    registered(client, "/rc", "/py")
    node.signal(signal.SIGINT)  # rclcpp's signal handler: shutdown, pre-shutdown first
    stopped = time.monotonic()
    system.manager.wait_for(
        lambda _: any("participant /rc dropped: left" in line for line in system.manager.lines),
        5,
        "/rc left",
    )
    assert time.monotonic() - stopped < 1.5, "left through rclcpp's pre-shutdown, not timed out"
    assert node.wait_exit() == 0
    assert {"event": "stopped", "following": False} in node.events


def test_a_lifecycle_node_follows_the_manager_and_is_driven_by_a_binding(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    layers = tmp_path / "flight.layers"
    layers.write_text("lifecycle Flight: drivers/propeller active\n", encoding="utf-8")
    # /drivers/propeller speaks the protocol under /drivers unless its topics are remapped
    # to those of the manager's namespace (docs/ros-integration.md, "Namespaces").
    remaps = [f"contextros/{topic}:=/contextros/{topic}" for topic in PROTOCOL_TOPICS]
    propeller = start(
        processes,
        "lifecycle node",
        program("lifecycle_node"),
        "--ros-args",
        *[word for remap in remaps for word in ("-r", remap)],
    )
    assert ready(propeller)["node"] == "/drivers/propeller"
    start_system(processes, client, ["py"], "--layers", str(layers))
    registered(client, "/drivers/propeller", "/py")

    flight = client.request(["Flight"], synchronous=True, timeout=5)
    assert flight.success, flight.message
    assert flight.acknowledged == ("/drivers/propeller", "/py")
    assert transitions_before(propeller, flight.epoch) == ["configure", "activate"], (
        "active before the node applied the state"
    )
    assert propeller.wait_applied(flight.epoch)["active"] == ["Flight"]

    landed = client.request([], ["Flight"], synchronous=True, timeout=5)
    assert landed.success, landed.message
    assert transitions_before(propeller, landed.epoch) == [
        "configure",
        "activate",
        "deactivate",
        "cleanup",
    ], "back to the state it had before Flight"


def test_two_components_in_one_container_share_one_participant_and_switch_together(
    client: LayerClient, processes: ProcessGroup
) -> None:
    container = start(
        processes, "container", str(PREFIX / "lib/rclcpp_components/component_container")
    )
    start_system(processes, client, ["py"])
    for plugin in ("Wheels", "Lights"):
        loader = start(
            processes,
            f"load {plugin}",
            program("load_component"),
            "/ComponentManager",
            "contextros_rclcpp_tests",
            f"contextros_rclcpp_tests::{plugin}",
        )
        loaded = loader.wait_for(
            lambda events: next((e for e in events if e["event"] == "loaded"), None), 20, "loaded"
        )
        assert loaded["success"], loaded
    registry = registered(client, "/wheels", "/py")
    carriers = [p for p in registry.participants if p.node in ("/wheels", "/lights")]
    assert [(p.node, list(p.hosted_nodes)) for p in carriers] == [("/wheels", ["/lights"])], (
        "one participant for the process, the second component hosted"
    )

    switched = client.request(["Slow", "Night"], synchronous=True, timeout=5)
    assert switched.success, switched.message
    assert set(switched.acknowledged) >= {"/wheels", "/py"}

    def behaviours(events: list[dict[str, Any]]) -> dict[str, str]:
        return {
            e["node"]: e["behaviour"]
            for e in events
            if e["event"] == "applied" and e["epoch"] == switched.epoch
        }

    seen = container.wait_for(lambda events: len(behaviours(events)) == 2, 5, "both rewired")
    assert seen and behaviours(container.events) == {"/wheels": "careful", "/lights": "on"}
