"""Misbehaving processes in the domain (issue 10), over real ROS: a forged status claiming
an absurd epoch, a layer name with a NUL byte, a request naming 100,000 layers, two live
processes under one name, and a participant cut off from its manager."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path
from typing import Any

import pytest
import rclpy
from contextros_interfaces.srv import Activate

from contextros.protocol import ActivationFailed
from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import start_system, wait_registry


def forge_status(client: LayerClient, count: int = 20, **fields: Any) -> None:
    """Publish status messages from the test process, as any process in the domain could."""
    import rclpy
    from contextros_interfaces.msg import LayerInfo, ParticipantStatus

    from contextros.ros import STATUS_QOS, STATUS_TOPIC

    publisher = client.node.create_publisher(ParticipantStatus, STATUS_TOPIC, STATUS_QOS)
    try:
        message = ParticipantStatus(
            node="/forger", incarnation="evil-1", layers=[LayerInfo(name="Night")], **fields
        )
        for _ in range(count):
            publisher.publish(message)
            rclpy.spin_once(client.node, timeout_sec=0.05)
    finally:
        client.node.destroy_publisher(publisher)


@pytest.mark.parametrize("epoch", [2**64 - 1, 10**15])
def test_a_forged_epoch_changes_nothing_and_never_reaches_the_state_file(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path, epoch: int
) -> None:
    state_file = tmp_path / "state.json"
    system = start_system(processes, client, ["u1"], "--state-file", str(state_file))
    before = client.query()
    forge_status(client, applied_epoch=epoch, active_layers=["Night"])
    result = client.request(["Night"], synchronous=True, timeout=5)
    assert result.success and result.epoch == before.epoch + 1, result.message
    assert json.loads(state_file.read_text())["epoch"] == result.epoch
    assert "/forger" not in {p.node for p in client.query().participants}
    system.manager.wait_for(
        lambda _: "ignored a status from '/forger'" in system.manager.output(), 5
    )
    # The manager restarts from its state file, as before.
    system.manager.signal(signal.SIGKILL)
    system.manager.wait_exit()
    processes.manager("--liveness-timeout", "1.0", "--state-file", str(state_file), name="m2")
    after = wait_registry(client, lambda r: r.epoch > result.epoch, what="restarted")
    assert after.epoch == result.epoch + 1


def test_bad_names_and_huge_requests_are_refused_with_a_small_answer(
    client: LayerClient, processes: ProcessGroup
) -> None:
    start_system(processes, client, ["u2"])
    before = client.query()
    # rclpy would cut the name at the NUL byte: the client refuses to send it.
    with pytest.raises(ActivationFailed, match=r"'Night\\x00evil' is not an identifier"):
        client.request(["Night\x00evil"], synchronous=True, timeout=5)
    # What the manager itself answers to any other process sending such requests.
    raw = client._activate
    for fields, culprit in [
        # 80 times the limit (260 kB): one shared-memory message; 100,000 names (1.3 MB,
        # fragments over UDP) once took over 30 s under a loaded full suite.
        ({"activate": [f"Layer{i}" for i in range(20_000)]}, "more than 256"),
        ({"activate": ["Night"], "synchronous": True, "timeout": float("nan")}, "timeout"),
        ({"activate": ["Ni ght"]}, "not an identifier"),
        ({"activate": ["Night"], "synchronous": True, "expect_nodes": ["x"]}, "expect_nodes"),
    ]:
        future = raw.call_async(Activate.Request(**fields))
        # Many names take seconds to convert on both sides of a loaded 2-core machine.
        rclpy.spin_until_future_complete(client.node, future, timeout_sec=30)
        response = future.result()
        assert response is not None, f"no answer within 30 s to the request naming {culprit!r}"
        assert not response.success
        assert culprit in response.message and "nothing changed" in response.message
        assert len(response.message) < 1000, "the answer stays small"
    assert client.query().epoch == before.epoch


def test_two_live_processes_with_one_name_are_both_tracked_and_shown(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["twin"])
    second = processes.participant("twin")
    second.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    registry = wait_registry(client, lambda r: list(r.conflicts) == ["/twin"], what="conflict")
    assert [p.conflict for p in registry.participants] == [True, True]
    # One of them cannot apply now: the other does not acknowledge for it.
    system.participants["twin"].send("critical 30")
    system.participants["twin"].wait_for(
        lambda events: any(e["event"] == "critical-open" for e in events), 5
    )
    result = client.request(["Night"], synchronous=True, timeout=1.0)
    assert not result.success and result.not_acknowledged == ("/twin",), result.message
    assert "two live processes are named so" in result.message
    from contextros.cli.ros_commands import _registry_as_text
    from contextros.ros.messages import registry_to_dict

    shown = _registry_as_text(registry_to_dict(registry))
    assert "CONFLICT: more than one live process is named /twin" in shown


def test_a_participant_knows_when_it_lost_the_manager_and_when_it_is_back(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["cut"])
    node = system.participants["cut"]
    system.manager.signal(signal.SIGKILL)
    killed = time.monotonic()
    lost = node.wait_for(
        lambda events: next((e for e in events if e["event"] == "manager-lost"), None), 10
    )
    # The bound counts from the last heartbeat heard, up to a few tenths before the kill on
    # a loaded machine: clearly not at once, though.
    assert lost["t"] - killed >= 1.5, "not before the liveness bound (3 s)"
    assert "no Layer manager heard for" in node.output()
    processes.manager("--liveness-timeout", "1.0", name="m2")
    node.wait_for(lambda events: any(e["event"] == "manager-found" for e in events), 15)


def test_a_status_with_invalid_utf8_is_ignored(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """Raw bytes any DDS writer can send: the manager neither crashes nor registers them."""
    from contextros_interfaces.msg import ParticipantStatus
    from rclpy.serialization import serialize_message

    from contextros.ros import STATUS_QOS, STATUS_TOPIC

    system = start_system(processes, client, ["u3"])
    before = client.query()
    raw = serialize_message(ParticipantStatus(node="/forgerX", incarnation="1"))
    raw = raw.replace(b"/forgerX", b"/forger\xff")
    publisher = client.node.create_publisher(ParticipantStatus, STATUS_TOPIC, STATUS_QOS)
    try:
        for _ in range(20):
            publisher.publish(raw)
            rclpy.spin_once(client.node, timeout_sec=0.05)
    finally:
        client.node.destroy_publisher(publisher)
    system.manager.wait_for(
        lambda _: "is not a fully qualified ROS node name" in system.manager.output(), 5
    )
    after = client.query()
    assert system.manager.popen.poll() is None, "the manager is alive"
    assert (after.epoch, [p.node for p in after.participants]) == (before.epoch, ["/u3"])


def test_commands_waiting_for_the_layers_ros_side_are_capped(client: LayerClient) -> None:
    """In the manager process itself: while bindings are driven, commands queue in the node
    (they were unbounded); beyond the cap each is refused at once, naming it."""
    from contextros.protocol import ManagerSettings
    from contextros.ros import LayerManagerNode

    manager = LayerManagerNode(
        settings=ManagerSettings(max_waiting_commands=2), node_name="capped_manager"
    )
    try:
        manager.bindings = object()  # type: ignore[assignment]  # commands queue in the node
        manager._driving = True  # as while a binding is being driven
        responses = []
        for _ in range(3):
            response = Activate.Response()
            request = Activate.Request(activate=["Night"], synchronous=True, timeout=1.0)
            responses.append(manager._on_activate(request, response))
        assert len(manager._commands) == 2
        assert [r.message for r in responses[:2]] == ["", ""], "waiting"
        assert not responses[2].success
        assert "at most 2 (max_waiting_commands)" in responses[2].message
    finally:
        manager.destroy_node()


def test_a_safe_fallback_gives_way_to_the_applied_state_when_the_manager_is_back(
    client: LayerClient,
) -> None:
    """Set while the manager was lost, a fallback configuration is replaced once the manager
    is heard again, even with the same epoch (its heartbeat is not newer than what was
    applied)."""
    from rclpy.node import Node

    from contextros.core import Layer, active_layers, set_active
    from contextros.protocol import LayerState
    from contextros.ros import ContextParticipant
    from contextros.ros.messages import state_to_msg

    del client  # only for rclpy, initialised in this process by the module's client fixture
    normal, safe = Layer("FallbackNormal"), Layer("FallbackSafe")
    node = Node("fallback_participant")
    participant = ContextParticipant(node, layers=[], manager_timeout=0.2)
    participant.add_manager_listener(lambda lost: set_active([safe]) if lost else None)
    try:
        state = LayerState(epoch=7, active=("FallbackNormal",), manager_id="m1")
        participant._on_state(state_to_msg(state, time.time()))
        assert [layer.name for layer in active_layers()] == [normal.name]
        deadline = time.monotonic() + 10
        while not participant.protocol.manager_lost and time.monotonic() < deadline:
            time.sleep(0.02)
            participant._on_heartbeat()
        assert [layer.name for layer in active_layers()] == [safe.name]
        participant._on_state(state_to_msg(state, time.time()))  # the manager's heartbeat
        assert not participant.protocol.manager_lost
        assert [layer.name for layer in active_layers()] == [normal.name]
        assert participant.applied_epoch == 7
    finally:
        participant.close()
        node.destroy_node()
        set_active([])


def test_a_forged_manager_heartbeat_does_not_make_the_manager_step_down(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """Another manager is one whose activate service the graph shows too: a heartbeat from
    a process that offers none (any process may publish one) stops nothing."""
    import rclpy
    from contextros_interfaces.msg import LayerState

    from contextros.ros.topics import HEARTBEAT_QOS, HEARTBEAT_TOPIC

    system = start_system(processes, client, ["u3"])
    before = client.query()
    publisher = client.node.create_publisher(LayerState, HEARTBEAT_TOPIC, HEARTBEAT_QOS)
    try:
        for forged_id in ("0", "1-forged", "recovering"):
            for _ in range(20):
                publisher.publish(LayerState(epoch=before.epoch + 5, manager_id=forged_id))
                rclpy.spin_once(client.node, timeout_sec=0.05)
    finally:
        client.node.destroy_publisher(publisher)
    result = client.request(["Night"], synchronous=True, timeout=5)
    assert result.success, result.message
    assert system.manager.popen.poll() is None
    assert "another Layer manager" not in system.manager.output()
