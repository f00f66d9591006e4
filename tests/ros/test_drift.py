"""The actual state, watched: a parameter or lifecycle state a layer set, changed afterwards
by another client, is reported as drift (status, --json, watch), set back (`on drift
restore`, bounded), or taken as a switch to the layer it matches (`on drift infer`)."""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.qos import qos_profile_parameter_events

from contextros.ros import LayerClient
from tests.ros.processes import HERE, Child, ProcessGroup
from tests.ros.system import LIVENESS, settle, wait_registry
from tests.ros.test_cli import contextros
from tests.ros.test_ros_bindings import call, max_speed, propeller_state

# The participant declares these layers (Slow excludes Fast; Gps requires Outdoor).
LAYERS = """\
parameter Slow: base max_speed = 0.3
parameter Fast: base max_speed = 3.0 on drift infer
parameter Night: base max_speed = 0.5 on drift restore
lifecycle Outdoor: propeller active
lifecycle Gps: propeller active on drift restore
"""


@pytest.fixture(scope="module")
def system(client: LayerClient, tmp_path_factory: pytest.TempPathFactory) -> Iterator[ProcessGroup]:
    layers = tmp_path_factory.mktemp("drift") / "robot.layers"
    layers.write_text(LAYERS, encoding="utf-8")
    group = ProcessGroup()
    try:
        start_system(group, client, layers, "d1")
        yield group
    finally:
        group.kill_all()


def start_system(
    group: ProcessGroup, client: LayerClient, layers: Path, participant: str, *plain: str
) -> Child:
    """The plain nodes (`plain`: their arguments), a participant and a manager of `layers`
    in `group`, each up; the manager."""
    nodes = group.start("plain nodes", [str(HERE / "plain_nodes_process.py"), *plain])
    group.participant(participant)
    manager = group.manager("--liveness-timeout", LIVENESS, "--layers", str(layers))
    nodes.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    client.wait_for_manager(15.0)
    wait_registry(client, lambda r: any(p.node == f"/{participant}" for p in r.participants))
    return manager


def manager(system: ProcessGroup) -> Child:
    return next(child for child in system.children if child.name == "manager")


def set_by_hand(client: LayerClient, value: float) -> None:
    """Another client (not the manager) sets /base max_speed."""
    parameter = Parameter(
        name="max_speed",
        value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
    )
    request = SetParameters.Request(parameters=[parameter])
    response = call(client, SetParameters, "/base/set_parameters", request)
    assert response.results[0].successful


def deactivate_by_hand(client: LayerClient) -> None:
    request = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_DEACTIVATE))
    assert call(client, ChangeState, "/propeller/change_state", request).success


def binding(registry: Any, layer: str) -> Any:
    return next(b for b in registry.bindings if b.layer == layer)


def wait_binding(
    client: LayerClient, layer: str, predicate: Callable[[Any], bool], what: str
) -> Any:
    registry = wait_registry(client, lambda r: predicate(binding(r, layer)), 5.0, what)
    return binding(registry, layer)


def eventually(predicate: Callable[[], bool], what: str, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_a_parameter_changed_by_hand_is_reported_with_what_is_seen_and_set(
    system: ProcessGroup, client: LayerClient
) -> None:
    settle(client, "Slow")
    assert binding(client.query(), "Slow").holds
    watch = system.start("watch", ["-m", "contextros", "watch", "--json", "--duration", "20"])
    watch.wait_for(lambda events: events, 15, "the watch's first record")
    before = time.time()
    set_by_hand(client, 1.5)
    slow = wait_binding(client, "Slow", lambda b: b.drifted, "Slow's binding drifted")
    assert (slow.observed, slow.value, slow.policy, slow.in_force) == ("1.5", "0.3", "report", True)
    since = slow.drifted_since.sec + slow.drifted_since.nanosec * 1e-9
    assert before - 0.5 <= since <= time.time()
    drift = watch.wait_for(
        lambda events: next((e for e in events if e["event"] == "drift"), None), 10, "drift"
    )
    assert (drift["layer"], drift["node"], drift["sets"], drift["seen"]) == (
        "Slow",
        "/base",
        "0.3",
        "1.5",
    )
    shown = contextros("status", "--json")
    assert shown.returncode == 0, shown.stderr
    data = json.loads(shown.stdout)
    (slow_json,) = [b for b in data["bindings"] if b["layer"] == "Slow"]
    assert slow_json["drifted"] and slow_json["observed"] == "1.5"
    assert "Slow" in data["active"] and "Slow" not in data["actual"]
    text = contextros("status").stdout
    assert "DRIFT: layer Slow sets /base max_speed = 0.3, the node has 1.5 since" in text
    assert "on drift report" in text and "they DIFFER" in text
    time.sleep(0.3)
    assert max_speed(client) == pytest.approx(1.5), "report only: nothing set back"
    set_by_hand(client, 0.3)
    wait_binding(client, "Slow", lambda b: not b.drifted and b.holds, "Slow holding again")
    watch.wait_for(lambda events: any(e["event"] == "drift-over" for e in events), 10, "drift-over")
    assert "Slow" in client_status()["actual"]


def client_status() -> dict[str, Any]:
    shown = contextros("status", "--json")
    assert shown.returncode == 0, shown.stderr
    return dict(json.loads(shown.stdout))


def test_a_forged_parameter_event_is_checked_on_the_node(
    system: ProcessGroup, client: LayerClient
) -> None:
    """Anyone can publish on /parameter_events: the manager reads the node before it
    believes a change, so a forged event makes no drift (and sets nothing back)."""
    settle(client, "Night")
    seen = len(manager(system).lines)
    publish_forged_max_speed(client, "/base", 7.0)
    night = binding(client.query(), "Night")
    assert night.holds and not night.drifted and night.observed == "0.5"
    assert not [line for line in manager(system).lines[seen:] if "back to" in line]


def publish_forged_max_speed(client: LayerClient, node: str, value: float) -> None:
    """Say 20 times on /parameter_events, as any process can, that `node`'s max_speed is
    `value` (it is not); then leave the subscribers half a second."""
    publisher = client.node.create_publisher(
        ParameterEvent, "/parameter_events", qos_profile_parameter_events
    )
    try:
        forged = ParameterEvent(
            node=node,
            changed_parameters=[
                Parameter(
                    name="max_speed",
                    value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
                )
            ],
        )
        eventually(lambda: publisher.get_subscription_count() > 0, "a subscriber")
        for _ in range(20):
            publisher.publish(forged)
            time.sleep(0.02)
        time.sleep(0.5)
    finally:
        client.node.destroy_publisher(publisher)


def test_restore_sets_a_parameter_back_and_logs_it(
    system: ProcessGroup, client: LayerClient
) -> None:
    settle(client, "Night")
    seen = len(manager(system).lines)
    set_by_hand(client, 2.0)
    eventually(lambda: max_speed(client) == pytest.approx(0.5), "max_speed set back to 0.5")
    line = manager(system).wait_for(
        lambda _: next((x for x in manager(system).lines[seen:] if "back to 0.5" in x), None),
        5,
        "the restore's log line",
    )
    assert "binding of layer Night" in line and "/base max_speed = 2" in line
    assert "set /base max_speed from 2 back to 0.5" in line
    wait_binding(client, "Night", lambda b: b.holds and not b.drifted, "Night holding again")


def test_two_fighting_writers_do_not_loop_forever(
    system: ProcessGroup, client: LayerClient
) -> None:
    """Set back at most 3 times within 30 s: then reported only, until a switch sets it."""
    settle(client)
    settle(client, "Night")  # a switch that sets max_speed: no restore counted before
    for _ in range(3):
        set_by_hand(client, 2.0)
        eventually(lambda: max_speed(client) == pytest.approx(0.5), "set back")
    set_by_hand(client, 2.0)
    night = wait_binding(
        client, "Night", lambda b: "not set back" in b.drift_action, "the restores given up"
    )
    assert "set back 3 times within 30 s" in night.drift_action
    time.sleep(0.3)
    assert max_speed(client) == pytest.approx(2.0), "the other writer's value stays"
    settle(client)  # Night leaves, and comes back: it is set back again from then on
    settle(client, "Night")
    set_by_hand(client, 2.0)
    eventually(lambda: max_speed(client) == pytest.approx(0.5), "set back after a switch")


def test_a_lifecycle_node_deactivated_by_another_client_is_reported(
    system: ProcessGroup, client: LayerClient
) -> None:
    settle(client, "Outdoor")
    assert propeller_state(client) == "active"
    deactivate_by_hand(client)
    outdoor = wait_binding(client, "Outdoor", lambda b: b.drifted, "Outdoor's binding drifted")
    assert (outdoor.kind, outdoor.node, outdoor.value, outdoor.observed) == (
        "lifecycle",
        "/propeller",
        "active",
        "inactive",
    )
    time.sleep(0.3)
    assert propeller_state(client) == "inactive", "report only"
    text = contextros("status").stdout
    assert "DRIFT: layer Outdoor sets lifecycle node /propeller active, the node has inactive" in (
        text
    )


def test_restore_brings_a_lifecycle_node_back(system: ProcessGroup, client: LayerClient) -> None:
    settle(client, "Outdoor", "Gps")  # Gps outermost: its `on drift restore` is in force
    assert propeller_state(client) == "active"
    seen = len(manager(system).lines)
    deactivate_by_hand(client)
    eventually(lambda: propeller_state(client) == "active", "the propeller active again")
    restored = "brought lifecycle node /propeller from inactive back to active (activate)"
    manager(system).wait_for(
        lambda _: any(restored in line for line in manager(system).lines[seen:]),
        5,
        "the restore's log line",
    )


def test_a_restarted_lifecycle_node_is_seen_and_brought_back(
    system: ProcessGroup, client: LayerClient
) -> None:
    """A lifecycle node restarting announces no transition: the manager sees it leave the
    graph and come back (new event publishers), reads it, and sets it back (Gps)."""
    settle(client, "Outdoor", "Gps")
    assert propeller_state(client) == "active"
    (plain,) = [c for c in system.children if c.name.startswith("plain") and c.popen.poll() is None]
    plain.signal(signal.SIGTERM)
    plain.wait_exit()
    gps = wait_binding(client, "Gps", lambda b: b.drifted, "the propeller gone")
    assert gps.observed == "(node not in the ROS graph)"
    restarted = system.start("plain nodes, restarted", [str(HERE / "plain_nodes_process.py")])
    restarted.wait_for(
        lambda events: any(e["event"] == "transition" and e["to"] == "active" for e in events),
        15,
        "the restarted propeller activated by the manager",
    )
    assert propeller_state(client) == "active"
    wait_binding(client, "Gps", lambda b: b.holds and not b.drifted, "Gps holding again")


def test_infer_switches_to_the_layer_whose_bindings_hold(
    system: ProcessGroup, client: LayerClient
) -> None:
    settle(client, "Fast")
    assert max_speed(client) == pytest.approx(3.0)
    set_by_hand(client, 0.3)  # what Slow sets
    registry = wait_registry(
        client, lambda r: list(r.active_layers) == ["Slow"], 5.0, "Slow inferred"
    )
    assert registry.requester == "contextros-inference"
    assert registry.reason == (
        "inferred: /base max_speed = 0.3 (layer Fast sets 3.0) is what layer Slow sets (and "
        "its bindings all hold)"
    )
    assert binding(registry, "Slow").holds and max_speed(client) == pytest.approx(0.3)
    set_by_hand(client, 9.5 / 2)  # a value no layer sets: Slow drifts, reported only
    slow = wait_binding(client, "Slow", lambda b: b.drifted, "Slow drifted")
    assert slow.observed == "4.75" and list(client.query().active_layers) == ["Slow"]
