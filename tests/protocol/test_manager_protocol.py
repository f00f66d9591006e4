"""The Layer manager's protocol, driven deterministically: a fake clock, no ROS."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerDeclaration,
    LayerState,
    ManagerAction,
    ManagerProtocol,
    ManagerSettings,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    ParticipantReport,
    PublishState,
    Reply,
)

SETTINGS = ManagerSettings(
    liveness_timeout=2.0,
    default_timeout=5.0,
    recovery_window=1.0,
    unknown_layer_grace=0.0,
    memoryless_epoch_gap=1,  # the gap has its own test (test_manager_promises.py)
)
INDOOR = LayerDeclaration("Indoor", group="location")
OUTDOOR = LayerDeclaration("Outdoor", group="location")
NIGHT = LayerDeclaration("Night")
SLOW = LayerDeclaration("Slow", excludes=frozenset({"Fast"}))
FAST = LayerDeclaration("Fast")
GPS = LayerDeclaration("Gps", requires=frozenset({"Outdoor"}))
ALL_LAYERS = (INDOOR, OUTDOOR, NIGHT, SLOW, FAST, GPS)


def report(
    node: str, applied: int = 0, active: Sequence[str] = (), **extra: object
) -> ParticipantReport:
    fields: dict[str, object] = {
        "node": node,
        "incarnation": "1",
        "layers": ALL_LAYERS,
        "applied_epoch": applied,
        "active": tuple(active),
    }
    fields.update(extra)
    return ParticipantReport(**fields)  # type: ignore[arg-type]


def states(actions: Sequence[ManagerAction]) -> list[LayerState]:
    return [a.state for a in actions if isinstance(a, PublishState)]


def replies(actions: Sequence[ManagerAction]) -> dict[int, ActivationResult]:
    return {a.request_id: a.result for a in actions if isinstance(a, Reply)}


class System:
    """A manager plus participants that apply whatever is published, when told to."""

    def __init__(self, nodes: Sequence[str] = ("/a", "/b", "/c")) -> None:
        self.now = 0.0
        self.manager = ManagerProtocol(self.now, SETTINGS)
        self.applied = dict.fromkeys(nodes, 0)
        self.log: list[ManagerAction] = []
        for node in nodes:
            self.feed(self.manager.receive_status(report(node), self.now))
        self.advance(SETTINGS.recovery_window)

    def feed(self, actions: Sequence[ManagerAction]) -> list[ManagerAction]:
        self.log += actions
        return list(actions)

    def advance(self, seconds: float) -> list[ManagerAction]:
        self.now += seconds
        return self.feed(self.manager.tick(self.now))

    def command(self, request_id: int, **fields: object) -> list[ManagerAction]:
        cmd = ActivationCommand(request_id=request_id, **fields)  # type: ignore[arg-type]
        return self.feed(self.manager.receive_command(cmd, self.now))

    def ack(self, node: str, **extra: object) -> list[ManagerAction]:
        state = self.manager.state
        self.applied[node] = state.epoch
        status = report(node, state.epoch, state.active, **extra)
        return self.feed(self.manager.receive_status(status, self.now))

    def heartbeat_all(self, except_: Sequence[str] = ()) -> None:
        for node, epoch in self.applied.items():
            if node not in except_:
                self.feed(self.manager.receive_status(report(node, epoch), self.now))


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


def test_async_activation_returns_once_published() -> None:
    system = System()
    actions = system.command(1, activate=("Indoor", "Night"), requester="cli", reason="test")
    (state,) = states(actions)
    assert (state.epoch, state.active, state.requester, state.reason) == (
        2,
        ("Indoor", "Night"),
        "cli",
        "test",
    )
    result = replies(actions)[1]
    assert result.success and result.epoch == 2 and result.active == ("Indoor", "Night")


def test_sync_activation_waits_for_every_live_participant() -> None:
    system = System()
    actions = system.command(1, activate=("Indoor",), synchronous=True)
    assert states(actions) and not replies(actions)
    assert not replies(system.ack("/a"))
    assert not replies(system.ack("/b"))
    result = replies(system.ack("/c"))[1]
    assert result.success
    assert result.acknowledged == ("/a", "/b", "/c") and result.not_acknowledged == ()
    assert "epoch 2" in result.message


def test_unknown_layer_is_rejected_by_name_and_changes_nothing() -> None:
    system = System()
    system.command(1, activate=("Indoor",))
    actions = system.command(2, activate=("Night", "Underwater"), synchronous=True)
    assert states(actions) == []
    result = replies(actions)[2]
    assert not result.success
    assert "'Underwater'" in result.message and "nothing changed" in result.message
    assert system.manager.state.epoch == 2 and system.manager.state.active == ("Indoor",)


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


@pytest.mark.parametrize(
    ("command", "culprit"),
    [
        ({"activate": ("Indoor", "Outdoor")}, "both in exclusive group 'location'"),
        ({"activate": ("Slow", "Fast")}, "Slow excludes Fast"),
        ({"activate": ("Gps",)}, "Gps requires Outdoor"),
        ({"activate": ("Night",), "deactivate": ("Night",)}, "both activated and deactivated"),
    ],
)
def test_relation_violations_are_rejected_with_nothing_changed(
    command: dict[str, tuple[str, ...]], culprit: str
) -> None:
    system = System()
    before = system.manager.state
    actions = system.command(1, synchronous=True, **command)
    result = replies(actions)[1]
    assert not result.success and culprit in result.message
    assert states(actions) == [] and system.manager.state == before


def test_switch_within_a_group_is_one_atomic_state() -> None:
    system = System()
    system.command(1, activate=("Indoor", "Night"))
    actions = system.command(2, activate=("Outdoor", "Gps"), deactivate=("Indoor",))
    (state,) = states(actions)
    assert state.active == ("Night", "Outdoor", "Gps")
    result = replies(system.command(3, activate=("Indoor",)))[3]
    assert not result.success and "Gps requires Outdoor" in result.message


def test_activating_a_group_member_drops_the_others_as_the_core_does() -> None:
    system = System()
    system.command(1, activate=("Outdoor", "Night"))
    (state,) = states(system.command(2, activate=("Indoor",)))
    assert state.active == ("Night", "Indoor")


def test_composition_order_is_activation_order_and_reactivation_keeps_place() -> None:
    system = System()
    system.command(1, activate=("Night",))
    system.command(2, activate=("Indoor",))
    assert system.manager.state.active == ("Night", "Indoor")
    actions = system.command(3, activate=("Night",))
    assert states(actions) == [] and replies(actions)[3].epoch == 3


def test_sync_timeout_names_the_nodes_that_did_not_acknowledge() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True, timeout=1.0)
    system.ack("/a")
    system.feed(
        system.manager.receive_status(
            report("/b", 1, pending_epoch=2, in_critical_section=True), system.now
        )
    )
    system.advance(0.5)
    system.heartbeat_all(except_=("/a", "/b"))
    result = replies(system.advance(0.6))[1]
    assert not result.success
    assert result.acknowledged == ("/a",)
    assert result.not_acknowledged == ("/b", "/c")
    assert (
        "/b (in a critical section" in result.message and "/c (still on epoch 0)" in result.message
    )
    assert result.elapsed == pytest.approx(1.1)


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


def test_failure_to_apply_is_reported_at_once() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.ack("/a")
    system.ack("/b")
    status = report("/c", 1, failed_epoch=2, error="epoch 2: hook of Night raised")
    result = replies(system.feed(system.manager.receive_status(status, system.now)))[1]
    assert (
        not result.success
        and "/c (failed to apply: epoch 2: hook of Night raised)" in result.message
    )


def test_a_newer_state_also_acknowledges_older_pending_activations() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.command(2, activate=("Indoor",), synchronous=True)
    for node in ("/a", "/b"):
        system.ack(node)
    done = replies(system.ack("/c"))
    assert done[1].success and done[2].success
    assert (done[1].epoch, done[2].epoch) == (2, 3)


def test_sync_with_no_change_confirms_the_current_epoch() -> None:
    system = System()
    for node in ("/a", "/b", "/c"):
        system.ack(node)
    actions = system.command(1, deactivate=("Night",), synchronous=True)
    assert states(actions) == [] and replies(actions)[1].success


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


def test_a_stale_report_does_not_take_a_node_back() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.ack("/a")
    stale = system.manager.receive_status(report("/a", 1), system.now + 0.1)
    assert stale == []
    view = system.manager.registry(system.now + 0.1)
    assert next(p for p in view.participants if p.node == "/a").applied_epoch == 2


def test_one_participant_speaks_for_the_other_nodes_of_its_process() -> None:
    system = System(nodes=("/host", "/solo"))
    system.feed(
        system.manager.receive_status(report("/host", hosted=("/guest1", "/guest2")), system.now)
    )
    view = system.manager.registry(system.now)
    assert {p.node: p.hosted for p in view.participants} == {
        "/host": ("/guest1", "/guest2"),
        "/solo": (),
    }
    system.command(1, activate=("Indoor",), synchronous=True)
    assert not replies(system.ack("/solo"))  # still waiting for /host (and so its guests)
    result = replies(system.ack("/host", hosted=("/guest1", "/guest2")))[1]
    assert result.success and "applied by 4 node(s)" in result.message
    assert result.acknowledged == ("/guest1", "/guest2", "/host", "/solo")


def test_nodes_hosted_by_a_silent_participant_are_named_with_it() -> None:
    system = System(nodes=("/host", "/solo"))
    system.feed(system.manager.receive_status(report("/host", hosted=("/guest",)), system.now))
    system.command(1, activate=("Night",), synchronous=True, timeout=1.0)
    system.ack("/solo")
    result = replies(system.advance(1.1))[1]
    assert not result.success
    assert result.not_acknowledged == ("/guest", "/host")
    assert "/guest (hosted by /host, still on epoch" in result.message


def test_a_change_of_nothing_says_no_change_sync_or_not() -> None:
    """Issue 12: not "acknowledged by 3 in 0.0 ms" for a deactivation of an inactive layer."""
    system = System()
    for node in ("/a", "/b", "/c"):
        system.ack(node)
    synchronous = replies(system.command(1, deactivate=("Night",), synchronous=True))[1]
    assert synchronous.message.startswith("no change")
    asynchronous = replies(system.command(2, deactivate=("Night",)))[2]
    assert asynchronous.message == "no change"


def test_a_refusal_names_the_layer_that_displaces_a_required_one() -> None:
    """Activating Flight drops Wheels (same exclusive group) while LowBattery requires
    Wheels: the refusal names all three layers and both relations."""
    wheels = LayerDeclaration("Wheels", group="mobility")
    flight = LayerDeclaration("Flight", group="mobility")
    low = LayerDeclaration("LowBattery", requires=frozenset({"Wheels"}))
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a", layers=(wheels, flight, low)), 0.0)
    manager.tick(SETTINGS.recovery_window)
    cmd = ActivationCommand(request_id=1, activate=("Wheels", "LowBattery"))
    assert replies(manager.receive_command(cmd, 1.1))[1].success
    refused = replies(
        manager.receive_command(ActivationCommand(request_id=2, activate=("Flight",)), 1.2)
    )[2]
    assert not refused.success
    message = refused.message
    assert "LowBattery requires Wheels" in message
    assert "activating Flight would deactivate Wheels" in message
    assert "exclusive group 'mobility'" in message and "nothing changed" in message


def test_a_refusal_names_a_displaced_layer_only_when_it_is_the_cause() -> None:
    wheels = LayerDeclaration("Wheels", group="mobility")
    flight = LayerDeclaration("Flight", group="mobility", excludes=frozenset({"LowBattery"}))
    low = LayerDeclaration("LowBattery")
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a", layers=(wheels, flight, low)), 0.0)
    manager.tick(SETTINGS.recovery_window)
    manager.receive_command(ActivationCommand(request_id=1, activate=("Wheels", "LowBattery")), 1.1)
    command = ActivationCommand(request_id=2, activate=("Flight",))
    refused = replies(manager.receive_command(command, 1.2))[2]
    assert "Flight excludes LowBattery" in refused.message
    assert "would deactivate" not in refused.message
