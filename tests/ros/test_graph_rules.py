"""Rules on the ROS graph's state in real processes: a manager's rule follows a real
lifecycle node that another client configures, activates and deactivates, and a real node's
parameter that another client sets; a node that is absent leaves its rule without a value."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node

from contextros.recording import read_recording
from contextros.ros import LayerClient
from contextros.ros.topics import MANAGER_NODE_NAME
from tests.ros.processes import HERE, Child, ProcessGroup
from tests.ros.system import LIVENESS, wait_registry
from tests.ros.test_cli import contextros
from tests.ros.test_drift import publish_forged_max_speed, start_system
from tests.ros.test_ros_bindings import call

# The plain nodes run in /drivers (`/drivers/base`, `/drivers/propeller`), the manager in
# /: the rules name them relative to the manager's namespace, as topics.
RULES = """\
rule Degraded: Slow while lifecycle drivers/propeller != active for 0.1 s
rule Careful: Night while param drivers/base.max_speed < 0.5
rule Ghost: Fast while lifecycle drivers/ghost == active
"""


@pytest.fixture(scope="module")
def system(client: LayerClient, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Child]:
    rules = tmp_path_factory.mktemp("graph_rules") / "robot.layers"
    rules.write_text(RULES, encoding="utf-8")
    group = ProcessGroup()
    try:
        yield start_system(group, client, rules, "g1", "--ros-args", "-r", "__ns:=/drivers")
    finally:
        group.kill_all()


def wait_active(client: LayerClient, layer: str, present: bool, what: str) -> None:
    wait_registry(client, lambda r: (layer in r.active_layers) == present, 10.0, what)


def transition(client: LayerClient, transition_id: int) -> None:
    request = ChangeState.Request(transition=Transition(id=transition_id))
    response = call(client, ChangeState, "/drivers/propeller/change_state", request)
    assert response.success, transition_id


def set_max_speed(client: LayerClient, value: float, node: str = "/drivers/base") -> None:
    parameter = Parameter(
        name="max_speed",
        value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
    )
    request = SetParameters.Request(parameters=[parameter])
    (result,) = call(client, SetParameters, f"{node}/set_parameters", request).results
    assert result.successful, result.reason


def rules_status(client: LayerClient) -> dict[str, dict[str, object]]:
    """Each rule as `contextros status` shows it (the manager's registry answer)."""
    return {
        rule.name: {"value": rule.value, "settled": rule.settled, "readings": list(rule.readings)}
        for rule in client.query().rules
    }


def test_a_lifecycle_rule_follows_the_node_from_its_first_state(
    client: LayerClient, system: Child
) -> None:
    # The node starts unconfigured: the rule knows it from get_state, with no transition.
    wait_active(client, "Slow", True, "Slow from the propeller's first state (unconfigured)")
    registry = client.query()
    assert registry.requester == "rule Degraded"
    assert registry.reason == "lifecycle drivers/propeller != active for 0.1 s (robot.layers:1)"
    transition(client, Transition.TRANSITION_CONFIGURE)
    transition(client, Transition.TRANSITION_ACTIVATE)
    wait_active(client, "Slow", False, "Slow off once another client activated the propeller")
    assert rules_status(client)["Degraded"]["readings"] == [
        "lifecycle drivers/propeller = 'active'"
    ]
    transition(client, Transition.TRANSITION_DEACTIVATE)
    wait_active(client, "Slow", True, "Slow again once another client deactivated it")
    assert client.query().requester == "rule Degraded"
    assert rules_status(client)["Degraded"]["readings"] == [
        "lifecycle drivers/propeller = 'inactive'"
    ]


def test_a_parameter_rule_switches_when_another_client_sets_the_parameter(
    client: LayerClient, system: Child
) -> None:
    deadline = time.monotonic() + 10
    while (rule := rules_status(client)["Careful"])["readings"] != [
        "param drivers/base.max_speed = 1.0"
    ]:
        assert time.monotonic() < deadline, f"the first value from get_parameters: {rule}"
        time.sleep(0.1)
    assert rule["value"] == "false"
    # Degraded's first reading of the propeller may come later on a loaded machine: its
    # firing (hold 0.1 s) must be over before the state checked below is Careful's.
    while rules_status(client)["Degraded"]["value"] == "no data":
        assert time.monotonic() < deadline, rules_status(client)["Degraded"]
        time.sleep(0.1)
    time.sleep(0.3)
    set_max_speed(client, 0.3)
    wait_active(client, "Night", True, "Night once another client set max_speed to 0.3")
    registry = client.query()
    assert (registry.requester, registry.reason) == (
        "rule Careful",
        "param drivers/base.max_speed < 0.5 (robot.layers:2)",
    )
    set_max_speed(client, 2.0)
    wait_active(client, "Night", False, "Night off once max_speed is 2.0")


def test_a_rule_on_an_absent_node_has_no_value(client: LayerClient, system: Child) -> None:
    ghost = rules_status(client)["Ghost"]
    assert (ghost["value"], ghost["settled"]) == ("no data", "")
    assert ghost["readings"] == ["lifecycle drivers/ghost = no value"]
    assert "Fast" not in client.query().active_layers
    assert any(
        "rules read the lifecycle states and parameters of /drivers/propeller, /drivers/ghost, "
        "/drivers/base" in line
        for line in system.lines
    ), system.output()


# Between two changes in the recording test: the replay's timer does not tick in the live
# manager's phase (a hold time ends up to one tick, 50 ms, apart), so two changes a few ms
# apart may switch in the other order there.
SETTLE = 0.2


def test_a_recording_replays_the_graph_rules_decisions(client: LayerClient, tmp_path: Path) -> None:
    """`contextros record --rules` keeps what the graph conditions saw (the events and the
    nodes' first answers): `rules replay --strict` makes the live manager's switches."""
    rules = tmp_path / "robot.layers"
    rules.write_text(RULES, encoding="utf-8")
    output, log = tmp_path / "run.mcap", tmp_path / "record.log"
    remap = ("--ros-args", "-r", "__ns:=/rec")
    group = ProcessGroup()
    node = Node("graph_rules_recording_client", namespace="/rec")
    rec = LayerClient(node, requester="pytest")
    recorder = None
    try:
        group.start(
            "rec plain nodes",
            [str(HERE / "plain_nodes_process.py"), "--ros-args", "-r", "__ns:=/rec/drivers"],
        )
        group.participant("g2", *remap)
        group.manager("--liveness-timeout", LIVENESS, "--rules", str(rules), *remap)
        rec.wait_for_manager(15.0)
        wait_registry(rec, lambda r: "Slow" in r.active_layers, 15.0, "Slow from the first state")
        # Recorded as a user records a running robot: from after the manager's start.
        command = ["record", str(output), "--rules", str(rules), "--namespace", "/rec"]
        with log.open("w") as stream:
            recorder = subprocess.Popen(
                [sys.executable, "-m", "contextros", *command], stdout=stream, stderr=stream
            )
        deadline = time.monotonic() + 20
        while not output.exists() or not {
            "/rec/contextros/state",
            "/rec/drivers/propeller/get_state",
            "/rec/drivers/base/get_parameters",
        } <= {m.topic for m in read_recording(output, truncated=lambda damage: None)}:
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        propeller = "/rec/drivers/propeller/change_state"
        for step in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
            call(rec, ChangeState, propeller, ChangeState.Request(transition=Transition(id=step)))
        wait_registry(rec, lambda r: "Slow" not in r.active_layers, 10.0, "Slow off")
        time.sleep(SETTLE)
        set_max_speed(rec, 0.3, "/rec/drivers/base")
        wait_registry(rec, lambda r: "Night" in r.active_layers, 10.0, "Night on")
        time.sleep(SETTLE)
        deactivate = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_DEACTIVATE))
        call(rec, ChangeState, propeller, deactivate)
        wait_registry(rec, lambda r: "Slow" in r.active_layers, 10.0, "Slow on again")
        time.sleep(SETTLE)
        set_max_speed(rec, 2.0, "/rec/drivers/base")
        wait_registry(rec, lambda r: "Night" not in r.active_layers, 10.0, "Night off")
        time.sleep(0.5)
        recorder.send_signal(signal.SIGINT)
        assert recorder.wait(20) == 0, log.read_text()
    finally:
        if recorder is not None and recorder.poll() is None:
            recorder.kill()
        group.kill_all()
        node.destroy_node()
    channels = {m.topic for m in read_recording(output)}
    assert {
        "/parameter_events",
        "/rec/drivers/base/get_parameters",
        "/rec/drivers/propeller/transition_event",
        "/rec/drivers/propeller/get_state",
    } <= channels, channels
    replayed = contextros(
        "rules",
        "replay",
        "--strict",
        "--json",
        str(output),
        "--rules",
        str(rules),
        "--namespace",
        "/rec",
    )
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    report = json.loads(replayed.stdout)
    by_rules = [
        (s["requester"], s["active"]) for s in report["switches"] if s["requester"] != "recording"
    ]
    assert by_rules[-4:] == [
        ("rule Degraded", []),
        ("rule Careful", ["Night"]),
        ("rule Degraded", ["Night", "Slow"]),
        ("rule Careful", ["Slow"]),
    ], report
    assert report["differences"] == [], report


def namespaced(
    tmp_path: Path, layers: str, namespace: str
) -> tuple[Path, ProcessGroup, Node, LayerClient]:
    """A layer file holding `layers`, a process group, and a client node in `namespace`."""
    path = tmp_path / "robot.layers"
    path.write_text(layers, encoding="utf-8")
    node = Node(f"graph_rules_client{namespace.replace('/', '_')}", namespace=namespace)
    return path, ProcessGroup(), node, LayerClient(node, requester="pytest")


def test_a_node_that_leaves_has_no_value_and_is_asked_again_when_it_returns(
    client: LayerClient, tmp_path: Path
) -> None:
    rules, group, node, gone = namespaced(tmp_path, RULES, "/gone")
    plain_nodes = [str(HERE / "plain_nodes_process.py"), "--ros-args", "-r", "__ns:=/gone/drivers"]

    def reading(expected: str, what: str) -> None:
        deadline = time.monotonic() + 15
        while (rule := rules_status(gone)["Degraded"])["readings"] != [expected]:
            assert time.monotonic() < deadline, f"{what}: {rule}"
            time.sleep(0.1)

    try:
        plain = group.start("leaving plain nodes", plain_nodes)
        group.manager("--rules", str(rules), "--ros-args", "-r", "__ns:=/gone")
        gone.wait_for_manager(15.0)
        reading("lifecycle drivers/propeller = 'unconfigured'", "the first answer")
        plain.signal(signal.SIGTERM)  # (a killed one stays on the graph for its lease)
        plain.wait_exit()
        reading("lifecycle drivers/propeller = no value", "no value once the node left")
        assert rules_status(gone)["Degraded"]["value"] == "no data"
        group.start("returning plain nodes", plain_nodes)
        reading("lifecycle drivers/propeller = 'unconfigured'", "asked again on its return")
    finally:
        group.kill_all()
        node.destroy_node()


def test_a_forged_parameter_event_changes_no_rule_value(client: LayerClient, system: Child) -> None:
    """Anyone can publish on /parameter_events: the manager reads the node when an event
    names it, and only the node's answer counts."""
    set_max_speed(client, 2.0)
    wait_active(client, "Night", False, "Night off with max_speed 2.0")
    publish_forged_max_speed(client, "/drivers/base", 0.1)
    assert rules_status(client)["Careful"]["readings"] == ["param drivers/base.max_speed = 2.0"]
    assert "Night" not in client.query().active_layers


# A graph rule and a binding on the same nodes, in one layer file (namespace /both).
BOTH = """\
parameter Slow: drivers/base max_speed = 0.3
lifecycle Outdoor: drivers/propeller active
rule Careful: Night while param drivers/base.max_speed > 2
rule Dark: Gps while lifecycle drivers/propeller == inactive
"""


def manager_subscriptions(node: Node, topic: str) -> int:
    return sum(
        1
        for info in node.get_subscriptions_info_by_topic(topic)
        if (info.node_namespace, info.node_name) == ("/both", MANAGER_NODE_NAME)
    )


def test_rules_and_bindings_share_one_subscription_per_topic_and_both_work(
    client: LayerClient, tmp_path: Path
) -> None:
    layers, group, node, both = namespaced(tmp_path, BOTH, "/both")
    try:
        group.start(
            "both plain nodes",
            [str(HERE / "plain_nodes_process.py"), "--ros-args", "-r", "__ns:=/both/drivers"],
        )
        group.participant("g4", "--ros-args", "-r", "__ns:=/both")
        group.manager("--layers", str(layers), "--ros-args", "-r", "__ns:=/both")
        both.wait_for_manager(15.0)
        wait_registry(both, lambda r: any(p.node == "/both/g4" for p in r.participants))
        result = both.request(["Slow", "Outdoor"], synchronous=True, timeout=5)
        assert result.success, result.message
        wait_registry(
            both,
            lambda r: (
                all(b.holds for b in r.bindings)
                and any(rule.readings == ["param drivers/base.max_speed = 0.3"] for rule in r.rules)
            ),
            10.0,
            "the bindings holding and the rule reading what they set",
        )
        topics = ("/parameter_events", "/both/drivers/propeller/transition_event")
        time.sleep(0.5)  # (discovery of the manager's endpoints)
        assert [manager_subscriptions(node, topic) for topic in topics] == [1, 1]
        # Another client sets max_speed and deactivates the propeller: the bindings drift
        # and the rules fire, from the same reads.
        set_max_speed(both, 3.0, "/both/drivers/base")
        deactivate = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_DEACTIVATE))
        assert call(both, ChangeState, "/both/drivers/propeller/change_state", deactivate).success
        registry = wait_registry(
            both,
            lambda r: (
                {"Night", "Gps"} <= set(r.active_layers) and all(b.drifted for b in r.bindings)
            ),
            10.0,
            "Night and Gps from the rules, both bindings drifted",
            show=group.children,
        )
        assert sorted((b.layer, b.observed) for b in registry.bindings) == [
            ("Outdoor", "inactive"),
            ("Slow", "3"),
        ]
    finally:
        group.kill_all()
        node.destroy_node()
