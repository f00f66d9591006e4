"""The promises of docs/protocol.md that the first real-network trials broke (issue 10),
each reproduced on the pure protocol first: own-epoch answers, expected nodes, the exact
dropped list, the restart grace period, same-name nodes, and manager heartbeats."""

from __future__ import annotations

from collections.abc import Sequence

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerDeclaration,
    LayerState,
    ManagerAction,
    ManagerProtocol,
    ManagerSettings,
    ParticipantConflict,
    ParticipantReport,
    PublishHeartbeat,
    PublishState,
    Reply,
)

LAYERS = (
    LayerDeclaration("Indoor", group="location"),
    LayerDeclaration("Outdoor", group="location"),
    LayerDeclaration("Night"),
)
SETTINGS = ManagerSettings(
    liveness_timeout=2.0, recovery_window=1.0, unknown_layer_grace=0.0, memoryless_epoch_gap=1
)


def report(
    node: str, applied: int = 0, active: Sequence[str] = (), **extra: object
) -> ParticipantReport:
    fields: dict[str, object] = {
        "node": node,
        "incarnation": "1",
        "layers": LAYERS,
        "applied_epoch": applied,
        "active": tuple(active),
    }
    fields.update(extra)
    return ParticipantReport(**fields)  # type: ignore[arg-type]


def states(actions: Sequence[ManagerAction]) -> list[LayerState]:
    return [a.state for a in actions if isinstance(a, PublishState)]


def replies(actions: Sequence[ManagerAction]) -> dict[int, ActivationResult]:
    return {a.request_id: a.result for a in actions if isinstance(a, Reply)}


def started(nodes: Sequence[str] = ("/a", "/b"), **settings: object) -> ManagerProtocol:
    manager = ManagerProtocol(0.0, ManagerSettings(**{**SETTINGS.__dict__, **settings}))
    for node in nodes:
        manager.receive_status(report(node), 0.0)
    manager.tick(1.0)
    return manager


def command(
    manager: ManagerProtocol, request_id: int, now: float, **fields: object
) -> list[ManagerAction]:
    return manager.receive_command(ActivationCommand(request_id, **fields), now)  # type: ignore[arg-type]


# -- an answer describes its own epoch ------------------------------------------------------


def test_a_synchronous_answer_carries_its_own_epochs_active_layers() -> None:
    manager = started(("/a",))
    first = states(command(manager, 1, 1.0, activate=("Indoor",), synchronous=True))[0]
    command(manager, 2, 1.0, activate=("Night",))  # another client, before the ack
    assert manager.state.active == ("Indoor", "Night")
    result = replies(manager.receive_status(report("/a", 3, ("Indoor", "Night")), 1.1))[1]
    assert result.success and result.epoch == first.epoch
    assert result.active == ("Indoor",), "the answer shows epoch 2's layers, not epoch 3's"


# -- a synchronous success needs the nodes it was meant to reach ----------------------------


def test_a_deactivation_that_reaches_nobody_fails() -> None:
    manager = started(("/a",))
    command(manager, 1, 1.0, activate=("Night",))
    manager.receive_status(report("/a", leaving=True), 1.1)
    result = replies(command(manager, 2, 1.2, deactivate=("Night",), synchronous=True))[2]
    assert not result.success and "reached no node" in result.message
    assert result.acknowledged == ()


def test_expected_nodes_must_apply_even_when_they_were_dropped_before() -> None:
    manager = started(("/local", "/remote"))
    manager.receive_status(report("/local", 1), 1.5)
    manager.tick(3.2)  # /remote silent: dropped before the command
    assert manager.live_nodes == ("/local",)
    actions = command(
        manager,
        1,
        3.3,
        activate=("Night",),
        synchronous=True,
        timeout=1.0,
        expect_nodes=("/local", "/remote"),
    )
    assert not replies(actions), "/local acknowledging alone is not enough"
    assert not replies(manager.receive_status(report("/local", 3, ("Night",)), 3.4))
    result = replies(manager.tick(4.4))[1]
    assert not result.success
    assert result.acknowledged == ("/local",) and result.not_acknowledged == ("/remote",)
    assert "expected node /remote did not apply it" in result.message


def test_an_expected_node_that_rejoins_in_time_makes_it_a_success() -> None:
    manager = started(("/local",))
    command(manager, 1, 1.0, activate=("Night",), synchronous=True, expect_nodes=("/remote",))
    manager.receive_status(report("/local", 2, ("Night",)), 1.1)
    assert not replies(manager.receive_status(report("/remote", 0), 1.2))
    result = replies(manager.receive_status(report("/remote", 2, ("Night",)), 1.3))[1]
    assert result.success and result.acknowledged == ("/local", "/remote")


def test_an_expected_count_counts_hosted_nodes() -> None:
    manager = started(("/host",))
    command(manager, 1, 1.0, activate=("Night",), synchronous=True, timeout=1.0, expect_count=3)
    reply = replies(manager.receive_status(report("/host", 2, hosted=("/g1",)), 1.1))
    assert reply == {}, "two nodes so far"
    result = replies(manager.tick(2.1))[1]
    assert not result.success and "applied by 2 node(s), 3 expected" in result.message
    command(manager, 2, 2.2, activate=("Indoor",), synchronous=True, expect_count=2)
    result = replies(manager.receive_status(report("/host", 3, hosted=("/g1",)), 2.3))[2]
    assert result.success and result.acknowledged == ("/g1", "/host")


# -- the dropped list is exact --------------------------------------------------------------


def test_dropped_list_has_no_repeats_and_forgets_nodes_that_rejoined() -> None:
    manager = started(("/a", "/b"))
    for round_ in range(3):
        now = 1.0 + round_ * 3
        manager.receive_status(report("/b"), now + 2.0)
        manager.tick(now + 2.5)  # /a silent each time (it rejoins in between)
        assert manager.dropped == ("/a",)
        manager.receive_status(report("/a"), now + 2.6)
        assert manager.dropped == ()


# -- a restarted manager: grace period, and nothing published before an epoch is known ------


def test_a_restarted_manager_holds_a_command_for_a_layer_not_heard_yet() -> None:
    manager = ManagerProtocol(
        0.0, ManagerSettings(recovery_window=1.0, unknown_layer_grace=2.0, memoryless_epoch_gap=1)
    )
    manager.tick(1.0)
    assert command(manager, 1, 1.1, activate=("Night",), synchronous=True) == []
    actions = manager.receive_status(report("/slow", 10, ("Indoor",)), 1.8)
    (recovered, night) = states(actions)
    assert (recovered.epoch, recovered.active) == (11, ("Indoor",))
    assert (night.epoch, night.active) == (12, ("Indoor", "Night"))
    result = replies(manager.receive_status(report("/slow", 12, ("Indoor", "Night")), 1.9))[1]
    assert result.success


def test_after_the_grace_period_an_unknown_layer_is_refused() -> None:
    manager = ManagerProtocol(
        0.0, ManagerSettings(recovery_window=1.0, unknown_layer_grace=2.0, memoryless_epoch_gap=1)
    )
    manager.receive_status(report("/a"), 0.5)
    manager.tick(1.0)
    assert command(manager, 1, 1.1, activate=("Underwater",)) == []
    assert replies(manager.tick(2.9)) == {}
    result = replies(manager.tick(3.1))[1]
    assert not result.success and "'Underwater'" in result.message


def test_a_manager_without_memory_publishes_nothing_before_it_hears_a_participant() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    published = [s for t in (1.0, 2.0, 3.0) for s in states(manager.tick(t))]
    assert published == []
    beats = [a.state.epoch for a in manager.tick(3.5) if isinstance(a, PublishHeartbeat)]
    assert beats == [0], "its heartbeat says it is alive, with no state"
    (state,) = states(manager.receive_status(report("/a", 10, ("Night",)), 3.6))
    assert (state.epoch, state.active) == (11, ("Night",))


# -- two live processes under one name ------------------------------------------------------


def test_two_live_nodes_sharing_a_name_are_both_tracked_and_neither_acks_for_the_other() -> None:
    manager = started(("/x",))
    manager.receive_status(report("/x", 1, incarnation="2"), 1.1)  # looks like a restart
    actions = manager.receive_status(report("/x", 1, incarnation="1"), 1.2)  # the first lives
    assert ParticipantConflict("/x") in actions
    view = manager.registry(1.2)
    assert [(p.node, p.incarnation, p.conflict) for p in view.participants] == [
        ("/x", "1", True),
        ("/x", "2", True),
    ]
    assert view.conflicts == ("/x",)
    command(manager, 1, 1.3, activate=("Night",), synchronous=True, timeout=1.0)
    assert replies(manager.receive_status(report("/x", 2, ("Night",), incarnation="2"), 1.4)) == {}
    result = replies(manager.tick(2.35))[1]
    assert not result.success and result.not_acknowledged == ("/x",)
    assert "two live processes are named so" in result.message
    # One leaves: the other is the only /x again, and acknowledges for itself.
    manager.receive_status(report("/x", 2, incarnation="1", leaving=True), 2.4)
    assert manager.conflicts() == ()
    command(manager, 2, 2.5, activate=("Indoor",), synchronous=True)
    result = replies(manager.receive_status(report("/x", 3, incarnation="2"), 2.6))[2]
    assert result.success and result.acknowledged == ("/x",)


# -- the manager's heartbeat ------------------------------------------------------------------


def test_a_new_state_is_repeated_on_the_heartbeat_shortly_after() -> None:
    manager = started(("/a",))
    manager.tick(1.3)
    (state,) = states(command(manager, 1, 1.31, activate=("Night",)))
    beats = []
    for step in range(1, 12):
        now = 1.31 + step * 0.05
        beats += [
            (round(now, 2), a.state.epoch)
            for a in manager.tick(now)
            if isinstance(a, PublishHeartbeat)
        ]
    assert beats[:2] == [(1.36, state.epoch), (1.46, state.epoch)]
    assert all(epoch == state.epoch for _, epoch in beats)
    assert len(beats) >= 3, "and every heartbeat period after that"


def test_no_repeat_once_every_node_has_the_state() -> None:
    manager = started(("/a",))
    manager.tick(1.3)
    (state,) = states(command(manager, 1, 1.31, activate=("Night",)))
    manager.receive_status(report("/a", state.epoch, ("Night",)), 1.33)
    beats = [
        round(now, 2)
        for now in (1.36, 1.41, 1.46, 1.51, 1.56, 1.61)
        for a in manager.tick(now)
        if isinstance(a, PublishHeartbeat)
    ]
    assert beats == [1.56], "only the regular heartbeat, 0.25 s after the last one"


def test_a_manager_without_memory_numbers_its_first_state_well_above_what_it_heard() -> None:
    # Its predecessor may have published epochs 11, 12... that no participant reported
    # during recovery (lost, or the node was cut off): never issue those numbers again.
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0))
    manager.receive_status(report("/a", 10, ("Night",)), 0.5)
    (state,) = states(manager.tick(1.0))
    assert (state.epoch, state.active) == (1010, ("Night",))
    fresh = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0))
    fresh.receive_status(report("/a", 0), 0.5)
    assert [s.epoch for s in states(fresh.tick(1.0))] == [1], "a new system starts at 1"
    with_file = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0), LayerState(10))
    with_file.receive_status(report("/a", 10, ("Night",)), 0.5)
    assert [s.epoch for s in states(with_file.tick(1.0))] == [11], "the file knows"
