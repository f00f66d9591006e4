"""Context nodes of one process share one participant: the configuration is per process."""

from __future__ import annotations

from contextros.protocol import LayerState
from contextros.ros import ContextNode, LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import wait_registry


def test_two_context_nodes_in_one_process_are_acknowledged_through_one_participant(
    client: LayerClient, processes: ProcessGroup
) -> None:
    host = processes.participant("host", "--also", "guest")
    host.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    processes.manager("--liveness-timeout", "1.0")
    client.wait_for_manager(15.0)
    registry = wait_registry(
        client,
        lambda r: r.epoch >= 1 and [list(p.hosted_nodes) for p in r.participants] == [["/guest"]],
        what="/host registered, hosting /guest",
    )
    assert [p.node for p in registry.participants] == ["/host"]
    assert "Night" in [layer.name for layer in registry.layers]  # the guest's layer
    result = client.request(["Night"], synchronous=True, timeout=5)
    assert result.success, result.message
    assert result.acknowledged == ("/guest", "/host")
    assert host.wait_applied(result.epoch)["mode"] == "quiet+base"


def test_the_next_context_node_takes_the_shared_participant_over(client: LayerClient) -> None:
    del client  # only for rclpy, initialised in this process by the module's client fixture
    first = ContextNode("first_of_process")
    second = ContextNode("second_of_process")
    third = ContextNode("third_of_process")
    own = ContextNode("own_participant", share_participant=False)
    seen: list[int] = []
    shared = first.context_participant
    shared.add_listener(lambda state: seen.append(state.epoch))
    assert second.context_participant is shared and third.context_participant is shared
    assert own.context_participant is not shared
    assert shared.hosted_nodes == ("/second_of_process", "/third_of_process")
    applied = LayerState(epoch=5, active=("Night",), manager_id="m1")
    shared.protocol.applied(applied, 0.0)  # as if the manager's state had been applied
    shared.state = applied

    first.destroy_node()
    successor = second.context_participant
    assert successor is not shared and successor.node is second
    # It carries on from the process's epoch, layers and manager (it started at epoch 0:
    # an older state could take the process back, a memoryless manager heard "nothing").
    assert successor.protocol.incarnation != shared.protocol.incarnation
    assert successor.applied_epoch == 5 and successor.state == applied
    report = successor.protocol.report()
    assert (report.active, report.applied_manager_id) == (("Night",), "m1")
    assert successor.protocol.receive_state(LayerState(epoch=4, active=()), 1.0) == []
    assert third.context_participant is successor
    assert successor.hosted_nodes == ("/third_of_process",)
    assert successor._listeners and successor._listeners[0].__name__ == "<lambda>"

    third.destroy_node()
    assert successor.hosted_nodes == ()
    # The listeners carried over still hear the states the successor applies.
    successor._listeners[0](LayerState(epoch=7, active=()))
    assert seen == [7]
    second.destroy_node()
    own.destroy_node()
