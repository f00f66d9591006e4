"""A (re)started manager's first state, and overtaking a participant ahead of it."""

from __future__ import annotations

from contextros.protocol import (
    ActivationCommand,
    LayerState,
    ManagerProtocol,
    ManagerSettings,
    ParticipantJoined,
    PublishHeartbeat,
)
from tests.protocol.manager.scenario import (
    SETTINGS,
    System,
    replies,
    report,
    states,
)


def test_recovery_publishes_a_first_state_after_listening_to_participants() -> None:
    system = System()
    published = states(system.log)
    assert [s.epoch for s in published] == [1]
    assert published[0].active == ()
    assert system.manager.live_nodes == ("/a", "/b", "/c")
    assert sum(isinstance(a, ParticipantJoined) for a in system.log) == 3


def test_commands_during_recovery_wait_for_it() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    assert manager.receive_command(ActivationCommand(7, activate=("Night",)), 0.1) == []
    actions = manager.tick(1.0)
    assert [s.epoch for s in states(actions)] == [1, 2]
    assert replies(actions)[7].success


def test_restart_recovers_active_set_and_epoch_from_participants() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a", 41, ("Outdoor",)), 0.2)
    manager.receive_status(report("/b", 42, ("Outdoor", "Night")), 0.3)
    (state,) = states(manager.tick(1.0))
    assert state.epoch == 43 and state.active == ("Outdoor", "Night")
    assert "recovered from /b" in state.reason


def test_restart_uses_the_state_file_when_it_is_newer() -> None:
    saved = LayerState(epoch=90, active=("Indoor",))
    manager = ManagerProtocol(0.0, SETTINGS, saved_state=saved)
    manager.receive_status(report("/a", 42, ("Outdoor",)), 0.2)
    (state,) = states(manager.tick(1.0))
    assert state.epoch == 91 and state.active == ("Indoor",)


def test_participant_ahead_of_a_manager_without_memory_is_overtaken() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    assert states(manager.tick(1.0)) == [], "nothing known yet: nothing published"
    (state,) = states(manager.receive_status(report("/late", 57, ("Night",)), 1.5))
    assert state.epoch == 58 and state.active == ("Night",)
    # Once a client decided here, the manager's own configuration is re-asserted instead.
    manager.receive_command(ActivationCommand(1, deactivate=("Night",)), 1.6)
    (state,) = states(manager.receive_status(report("/older", 70, ("Indoor",)), 1.7))
    assert state.epoch == 71 and state.active == ()


def test_recovery_is_prolonged_while_participants_keep_appearing() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a", 7, ("Night",)), 0.9)
    assert states(manager.tick(1.0)) == [], "a newcomer just appeared: keep listening"
    manager.receive_status(report("/b", 9, ("Indoor",)), 1.1)
    (state,) = states(manager.tick(1.5))
    assert state.epoch == 10 and state.active == ("Indoor",)


def test_recovery_ends_within_three_windows_whatever_happens() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    for step in range(1, 40):
        now = step * 0.1
        manager.receive_status(report(f"/n{step}"), now)
        if states(manager.tick(now)):
            break
    assert not manager.recovering and now <= 3 * SETTINGS.recovery_window + 0.1


def test_a_state_of_another_manager_with_our_epoch_is_overtaken() -> None:
    # m3 started without memory and heard only stale reports: it numbered its first state
    # like the one its predecessor published; the nodes, on the predecessor's, report it.
    manager = ManagerProtocol(
        0.0, ManagerSettings(recovery_window=1.0, manager_id="m3", memoryless_epoch_gap=1)
    )
    manager.receive_status(report("/a", 3, ("Night",)), 0.5)
    (mine,) = states(manager.tick(1.0))
    assert mine.epoch == 4
    theirs = report("/a", 4, ("Indoor",), applied_manager_id="m2")
    (state,) = states(manager.receive_status(theirs, 1.2))
    assert state.epoch == 5 and state.active == ("Indoor",)
    ours = report("/a", 5, ("Indoor",), applied_manager_id="m3")
    assert states(manager.receive_status(ours, 1.3)) == []


def test_a_manager_without_memory_publishes_nothing_before_it_hears_a_participant() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    published = [s for t in (1.0, 2.0, 3.0) for s in states(manager.tick(t))]
    assert published == []
    beats = [a.state.epoch for a in manager.tick(3.5) if isinstance(a, PublishHeartbeat)]
    assert beats == [0], "its heartbeat says it is alive, with no state"
    (state,) = states(manager.receive_status(report("/a", 10, ("Night",)), 3.6))
    assert (state.epoch, state.active) == (11, ("Night",))


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


def test_recovery_prolonged_while_another_manager_is_seen_ends_within_three_windows() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a", 7, ("Night",)), 0.2)
    for step in range(10, 40):  # the adapter sees another manager's service, unheard
        now = step * 0.1
        manager.prolong_recovery(now + 0.1)
        if states(manager.tick(now)):
            break
    assert not manager.recovering
    assert 3 * SETTINGS.recovery_window - 0.05 <= now <= 3 * SETTINGS.recovery_window + 0.1
