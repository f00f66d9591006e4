"""Who is live: joins, restarts, name clashes, silence, leaving, the registry view."""

from __future__ import annotations

import pytest

from contextros.protocol import (
    LayerDeclaration,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    PublishHeartbeat,
    Reply,
)
from tests.protocol.manager.scenario import (
    ALL_LAYERS,
    SETTINGS,
    System,
    command,
    replies,
    report,
    started,
)


def test_dead_participant_is_dropped_within_the_liveness_bound_and_named() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True, timeout=30.0)
    system.ack("/a")
    system.ack("/b")
    for _ in range(8):  # /c died: only /a and /b keep their heartbeat
        system.heartbeat_all(except_=("/c",))
        system.advance(0.25)
    dropped = [a for a in system.log if isinstance(a, ParticipantDropped)]
    assert [d.node for d in dropped] == ["/c"]
    result = next(a.result for a in system.log if isinstance(a, Reply))
    assert not result.success and result.not_acknowledged == ("/c",)
    assert "/c (dropped, silent for" in result.message
    assert result.elapsed <= SETTINGS.liveness_timeout + 0.25
    # The next activation succeeds without it.
    system.command(2, activate=("Indoor",), synchronous=True)
    system.ack("/a")
    result = replies(system.ack("/b"))[2]
    assert result.success and result.acknowledged == ("/a", "/b")


def test_leaving_participant_is_dropped_at_once() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.ack("/a")
    system.ack("/b")
    actions = system.feed(system.manager.receive_status(report("/c", leaving=True), system.now))
    assert ParticipantDropped("/c", "left") in actions
    assert not replies(actions)[1].success


def test_layer_known_only_from_a_dead_participant_is_unknown() -> None:
    system = System(nodes=("/a",))
    system.feed(
        system.manager.receive_status(report("/b", layers=(LayerDeclaration("Dock"),)), system.now)
    )
    assert replies(system.command(1, activate=("Dock",)))[1].success
    system.heartbeat_all()
    system.advance(2.5)  # /b is silent and dropped
    result = replies(system.command(2, activate=("Dock",)))[2]
    assert not result.success and "'Dock'" in result.message
    result = replies(system.command(3, deactivate=("Dock",)))[3]
    assert result.success, "an active layer can always be deactivated"
    assert system.manager.state.active == ()


def test_registry_shows_layers_nodes_and_laggards() -> None:
    system = System()
    system.command(1, activate=("Night",))
    system.ack("/a")
    view = system.manager.registry(system.now + 0.5)
    assert view.state.epoch == 2
    assert view.implemented_by["Night"] == ("/a", "/b", "/c")
    lagging = {p.node for p in view.participants if p.lagging}
    assert lagging == {"/b", "/c"}
    assert {d.name for d in view.layers} == {d.name for d in ALL_LAYERS}
    assert next(d for d in view.layers if d.name == "Indoor").group == "location"


def test_restart_of_a_participant_is_told_apart_from_two_nodes_sharing_a_name() -> None:
    system = System(nodes=("/a",))
    restarted = system.manager.receive_status(report("/a", incarnation="2"), system.now)
    assert ParticipantJoined("/a", restarted=True) in restarted
    stale_leave = report("/a", incarnation="1", leaving=True)
    assert system.manager.receive_status(stale_leave, system.now) == []
    assert system.manager.live_nodes == ("/a",), "the old process leaving drops nobody"
    twin = system.manager.receive_status(report("/a", incarnation="1"), system.now)
    assert twin == [ParticipantConflict("/a")]
    for incarnation in ("2", "1", "2"):
        assert system.manager.receive_status(report("/a", incarnation=incarnation), 0.0) == []


def test_a_stale_report_does_not_take_a_node_back() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.ack("/a")
    stale = system.manager.receive_status(report("/a", 1), system.now + 0.1)
    assert stale == []
    view = system.manager.registry(system.now + 0.1)
    assert next(p for p in view.participants if p.node == "/a").applied_epoch == 2


def test_nodes_hosted_by_a_silent_participant_are_named_with_it() -> None:
    system = System(nodes=("/host", "/solo"))
    system.feed(system.manager.receive_status(report("/host", hosted=("/guest",)), system.now))
    system.command(1, activate=("Night",), synchronous=True, timeout=1.0)
    system.ack("/solo")
    result = replies(system.advance(1.1))[1]
    assert not result.success
    assert result.not_acknowledged == ("/guest", "/host")
    assert "/guest (hosted by /host, still on epoch" in result.message


def test_dropped_list_has_no_repeats_and_forgets_nodes_that_rejoined() -> None:
    manager = started(("/a", "/b"))
    for round_ in range(3):
        now = 1.0 + round_ * 3
        manager.receive_status(report("/b"), now + 2.0)
        manager.tick(now + 2.5)  # /a silent each time (it rejoins in between)
        assert manager.dropped == ("/a",)
        manager.receive_status(report("/a"), now + 2.6)
        assert manager.dropped == ()


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


def test_time_the_manager_did_not_run_is_nobodys_silence() -> None:
    """Its process waited 5 s for a core (liveness bound 2 s): the reports sent meanwhile
    are still on their way in, so nobody is dropped; a node that stays silent afterwards
    is dropped one bound of the manager's own running time later."""
    system = System()
    system.heartbeat_all()
    system.now += 5.0
    system.manager.resumed_after(5.0)
    assert not [a for a in system.advance(0.05) if isinstance(a, ParticipantDropped)]
    for _ in range(10):  # /a and /b report again, /c does not
        system.heartbeat_all(except_=("/c",))
        system.advance(0.25)
    dropped = [a.node for a in system.log if isinstance(a, ParticipantDropped)]
    assert dropped == ["/c"]


def test_the_heartbeat_period_grows_with_the_participants_and_the_liveness_bound_with_it() -> None:
    """Beyond `status_rate` statuses per second at the settings' period, the manager asks
    for a longer period (25% headroom) and waits as many periods before a drop; back under
    40% of the rate, the shorter period again, with the longer bound for as long as a
    participant may not have heard it yet."""
    nodes = ("/a", "/b", "/c", "/d", "/e")
    manager = started(nodes, status_rate=8.0)  # 5 participants: 20 statuses/s at 0.25 s
    period = 1.25 * 5 / 8.0
    assert manager.status_period == pytest.approx(period)
    assert manager.liveness_bound(1.0) == pytest.approx(SETTINGS.liveness_timeout * period / 0.25)
    (beat,) = [a for a in manager.tick(1.3) if isinstance(a, PublishHeartbeat)]
    assert beat.state.status_period == pytest.approx(period), "the heartbeat carries it"
    manager.receive_status(report("/a"), 6.0)  # the others fall silent at 1.0 s
    assert not [a for a in manager.tick(6.0) if isinstance(a, ParticipantDropped)], (
        "5 s of silence: within the longer bound (6.25 s)"
    )
    dropped = [a.node for a in manager.tick(7.3) if isinstance(a, ParticipantDropped)]
    assert dropped == ["/b", "/c", "/d", "/e"]
    manager.tick(7.35)
    assert manager.status_period == SETTINGS.status_period, "1 participant: back to 0.25 s"
    assert manager.liveness_bound(7.4) == pytest.approx(6.25), "until they all heard it"
    assert manager.liveness_bound(7.35 + 6.26) == SETTINGS.liveness_timeout
    dropped = [a.node for a in manager.tick(12.1) if isinstance(a, ParticipantDropped)]
    assert dropped == [], "/a, silent 6.1 s, still under the longer bound"
    dropped = [a.node for a in manager.tick(12.4) if isinstance(a, ParticipantDropped)]
    assert dropped == ["/a"], "/a silent 6.4 s, past it"
