"""A participant's side of the protocol: never back to an older epoch, honest acknowledgements."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from contextros.protocol import (
    ApplyState,
    LayerDeclaration,
    LayerState,
    ManagerLost,
    ParticipantProtocol,
    PublishStatus,
)


def participant() -> ParticipantProtocol:
    return ParticipantProtocol("/p", "inc-1", (LayerDeclaration("Night"),), heartbeat_period=0.25)


def test_new_state_is_applied_and_acknowledged() -> None:
    p = participant()
    state = LayerState(3, ("Night",))
    assert p.receive_state(state) == [ApplyState(state)]
    (action,) = p.applied(state, now=0.0)
    assert isinstance(action, PublishStatus)
    assert (action.report.applied_epoch, action.report.active) == (3, ("Night",))


def test_stale_and_duplicate_states_are_ignored() -> None:
    p = participant()
    newer, older = LayerState(5, ("Night",)), LayerState(4, ())
    p.applied(newer, now=0.0)
    assert p.receive_state(older) == []
    assert p.receive_state(newer) == []
    assert p.applied(older, now=0.1) == [] and p.applied_epoch == 5


def test_deferred_state_is_reported_pending_and_acknowledged_only_once_applied() -> None:
    p = participant()
    state = LayerState(2, ("Night",))
    p.receive_state(state)
    (deferred,) = p.deferred(state, now=0.0)
    assert isinstance(deferred, PublishStatus)
    assert deferred.report.in_critical_section and deferred.report.pending_epoch == 2
    assert deferred.report.applied_epoch == 0
    assert p.receive_state(state) == [], "a scheduled epoch is not applied twice"
    (applied,) = p.applied(state, now=0.5)
    assert isinstance(applied, PublishStatus)
    assert applied.report.applied_epoch == 2 and not applied.report.in_critical_section


def test_newer_state_while_deferred_is_passed_on_behind_it() -> None:
    p = participant()
    p.deferred(LayerState(2, ("Night",)), now=0.0)
    assert p.receive_state(LayerState(3, ())) == [ApplyState(LayerState(3, ()))]


def test_failure_is_reported_and_not_retried() -> None:
    p = participant()
    state = LayerState(2, ("Night",))
    (action,) = p.failed(state, "Night requires Dark", now=0.0)
    assert isinstance(action, PublishStatus)
    assert action.report.failed_epoch == 2 and "Night requires Dark" in action.report.error
    assert p.receive_state(state) == []


def test_heartbeat_period_and_repeats_of_a_new_report() -> None:
    p = participant()
    assert len(p.announce(0.0)) == 1
    assert p.next_repeat == 0.05
    assert len(p.tick(0.05)) == 1, "repeated shortly after: a lossy link may have lost it"
    assert p.tick(0.1) == []
    assert len(p.tick(0.15)) == 1
    assert p.next_repeat is None
    assert p.tick(0.3) == []
    assert len(p.tick(0.41)) == 1, "then the heartbeat"
    (leaving,) = p.leave(0.3)
    assert isinstance(leaving, PublishStatus) and leaving.report.leaving


def test_reports_are_repeated_only_while_the_link_shows_loss() -> None:
    p = participant()
    p.announce(0.0)
    for beat in range(1, 5):  # the manager's heartbeat, on time: a clean link
        p.receive_state(LayerState(1, ()), now=beat * 0.25)
        p.tick(beat * 0.25)
    p.applied(LayerState(2, ("Night",)), now=1.0)
    assert p.next_repeat is None, "a clean link: no repeat, the manager is not loaded"
    p.receive_state(LayerState(2, ("Night",)), now=1.5)  # 0.5 s after the last: one lost
    (ack,) = p.applied(LayerState(3, ()), now=1.6)
    assert p.next_repeat == pytest.approx(1.65) and ack.report.applied_epoch == 3
    assert [a.report.applied_epoch for a in p.tick(1.65)] == [3], "repeated: loss was seen"
    assert len(p.tick(1.75)) == 1 and p.next_repeat is None
    for beat in range(1, 130):  # 32 s of heartbeats on time: the loss is forgotten
        p.receive_state(LayerState(3, ()), now=1.6 + beat * 0.25)
    p.applied(LayerState(4, ("Night",)), now=34.0)
    assert p.next_repeat is None


def test_an_open_critical_section_is_reported_even_with_nothing_deferred() -> None:
    p = participant()
    p.critical_section_open = True
    (action,) = p.announce(0.0)
    assert isinstance(action, PublishStatus)
    assert action.report.in_critical_section and action.report.pending_epoch == 0


def test_hosting_other_nodes_reannounces_with_their_layers() -> None:
    from contextros.protocol import LayerDeclaration, ParticipantProtocol, PublishStatus

    own = (LayerDeclaration("Indoor"),)
    participant = ParticipantProtocol("/host", "1", own)
    more = (LayerDeclaration("Indoor"), LayerDeclaration("Night"))
    (action,) = participant.host(("/guest",), more, now=1.0)
    assert isinstance(action, PublishStatus)
    assert action.report.hosted == ("/guest",)
    assert [d.name for d in action.report.layers] == ["Indoor", "Night"]


def test_an_error_spanning_lines_is_reported_flat() -> None:
    from contextros.protocol.validation import report_problems

    p = participant()
    (action,) = p.failed(LayerState(2, ("Night",)), "line one\nline two", now=0.0)
    assert isinstance(action, PublishStatus)
    assert "line one line two" in action.report.error
    assert report_problems(action.report) == [], "the manager accepts it"


def test_a_vote_is_yes_unless_a_critical_section_or_a_relation_says_no() -> None:
    p = ParticipantProtocol(
        "/p", "1", (LayerDeclaration("Gps", requires=frozenset({"Outdoor"})),), repeats=()
    )
    (yes,) = p.receive_proposal(LayerState(2, ("Outdoor", "Gps")), now=0.0)
    assert isinstance(yes, PublishStatus)
    assert (yes.report.vote_epoch, yes.report.vote_yes) == (2, True)
    assert p.receive_proposal(LayerState(2, ("Outdoor", "Gps")), now=0.1) == [], "voted once"
    assert p.applied_epoch == 0, "a vote changes nothing"
    (no,) = p.receive_proposal(LayerState(3, ("Gps",)), now=0.2)
    assert isinstance(no, PublishStatus) and not no.report.vote_yes
    assert "Gps requires Outdoor" in no.report.vote_reason
    p.critical_section_open = True
    (busy,) = p.receive_proposal(LayerState(4, ("Outdoor",)), now=0.3, veto="arm moving")
    assert isinstance(busy, PublishStatus)
    assert busy.report.vote_reason == "arm moving; in a critical section"


def test_the_vetoes_are_wanted_once_per_proposal() -> None:
    # The adapter asks the application's vetoes only while `wants_vote` (issue 24: up to
    # 61 calls for one proposal repeated every 50 ms); meanwhile a repeat votes nothing.
    p = ParticipantProtocol("/p", "1", (LayerDeclaration("Night"),), repeats=())
    proposal = LayerState(2, ("Night",), manager_id="m1")
    assert p.wants_vote(proposal)
    heard = p.receive_proposal(proposal, now=0.0, vote=False)  # a new manager: it reports
    assert [a.report.vote_epoch for a in heard if isinstance(a, PublishStatus)] == [0]
    assert p.wants_vote(proposal) and p.vote_epoch == 0, "heard, not voted"
    p.receive_proposal(proposal, now=0.1, veto="busy")
    assert not p.wants_vote(proposal)
    assert not p.wants_vote(LayerState(2, ("Night",), manager_id="m1")), "a repeat"
    assert p.wants_vote(LayerState(2, ("Night",), manager_id="m2")), "another manager's"
    # A late copy of an older proposal, after a newer one was voted on, is over (the
    # explorer's 7-event trace: vetoes asked twice, two votes on one proposal).
    p.receive_proposal(LayerState(3, ("Night",), manager_id="m1"), now=0.2)
    assert not p.wants_vote(proposal)
    assert p.receive_proposal(proposal, now=0.3) == [] and p.vote_epoch == 3


def test_a_successor_carries_on_from_the_participant_it_replaces() -> None:
    # The carrier node of a process goes; the next node carries a new participant (a new
    # incarnation) for the same process, whose layers are still those applied before.
    previous = participant()
    applied = LayerState(5, ("Night",), manager_id="m1")
    previous.receive_state(applied, now=0.0)
    previous.applied(applied, now=0.0)
    successor = ParticipantProtocol("/q", "inc-2", (LayerDeclaration("Night"),))
    successor.continue_from(previous)
    (announced,) = successor.announce(now=1.0)
    assert isinstance(announced, PublishStatus)
    report = announced.report
    assert (report.applied_epoch, report.active, report.applied_manager_id) == (
        5,
        ("Night",),
        "m1",
    )
    assert successor.receive_state(LayerState(4, ()), now=1.1) == [], "never back a state"
    assert successor.receive_state(applied, now=1.2) == [], "the same manager: nothing new"
    newer = LayerState(6, (), manager_id="m1")
    assert successor.receive_state(newer, now=1.3) == [ApplyState(newer)]


def test_a_memoryless_manager_recovers_a_handed_over_process_s_layers() -> None:
    from contextros.protocol import ManagerProtocol, ManagerSettings, PublishState

    previous = participant()
    applied = LayerState(5, ("Night",), manager_id="m1")
    previous.applied(applied, now=0.0)
    successor = ParticipantProtocol("/q", "inc-2", (LayerDeclaration("Night"),))
    successor.continue_from(previous)
    (announced,) = successor.announce(now=0.0)
    assert isinstance(announced, PublishStatus)
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0, manager_id="m2"))
    manager.receive_status(announced.report, 0.1)
    (state,) = [a.state for a in manager.tick(1.0) if isinstance(a, PublishState)]
    assert state.active == ("Night",) and state.epoch > 5
    assert state.reason == "recovered from /q"


def test_the_heartbeat_period_is_the_longer_one_the_manager_asks_for() -> None:
    """As the C++ participant's test of the same name."""
    p = ParticipantProtocol("/p", "inc-1", (LayerDeclaration("Night"),), 0.25, 3.0)
    p.announce(0.0)
    p.tick(0.05)  # the announcement's repeats
    p.tick(0.15)
    slower = LayerState(1, (), manager_id="m1", status_period=2.0)  # many participants
    p.receive_state(slower, now=0.2)  # a new manager: reported at once, and repeated
    p.applied(slower, now=0.2)
    p.tick(0.25)
    (last,) = p.tick(0.35)
    assert isinstance(last, PublishStatus) and last.report.applied_epoch == 1
    assert p.status_period == 2.0 and p.next_tick == pytest.approx(0.35 + 1.6)
    assert p.tick(1.0) == [], "no heartbeat every 0.25 s any more"
    p.receive_state(slower, now=1.5)  # its heartbeat: the manager is still there
    assert p.tick(1.9) == []
    assert len(p.tick(1.95)) == 1, "after 80% of the period"
    p.receive_state(replace(slower, status_period=0.1), now=1.96)
    assert p.status_period == 0.25, "never below the node's own period"
    p.receive_state(replace(slower, status_period=1e9), now=1.97)
    assert p.status_period == 60.0, "a forged period silences the node for a minute at most"
    p.receive_state(replace(slower, status_period=math.nan), now=1.98)
    assert p.status_period == 0.25
    lost = p.tick(5.0)
    assert isinstance(lost[0], ManagerLost) and p.status_period == 0.25
