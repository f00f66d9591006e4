"""Everything from the network is untrusted: every field of every message and service is
checked, and a bad one changes nothing (issue 10: one status claiming epoch 2**64-1 crashed
the manager and poisoned its state file; 10**15 made the whole system jump; 'Night\\x00evil'
activated Night; 100,000 unknown layers got a 1.4 MB reply)."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from contextros.protocol import (
    MAX_EPOCH,
    ActivationCommand,
    ApplyState,
    LayerDeclaration,
    LayerState,
    ManagerProtocol,
    ManagerSettings,
    ParticipantProtocol,
    ParticipantReport,
    PublishState,
    Reply,
    ReportRejected,
    StateFileError,
    StateRejected,
)

NIGHT = LayerDeclaration("Night")
GOOD = ParticipantReport(node="/a", incarnation="1", layers=(NIGHT,))
LONG = "x" * 2000

BAD_REPORTS: list[tuple[str, dict[str, Any]]] = [
    ("node", {"node": ""}),
    ("node", {"node": "a"}),
    ("node", {"node": "/a\x00b"}),
    ("node", {"node": "/" + "a" * 300}),
    ("node", {"node": "/a b"}),
    ("incarnation", {"incarnation": ""}),
    ("incarnation", {"incarnation": "1\x00"}),
    ("incarnation", {"incarnation": LONG}),
    ("layer name", {"layers": (LayerDeclaration("Night\x00evil"),)}),
    ("layer name", {"layers": (LayerDeclaration(""),)}),
    ("layer name", {"layers": (LayerDeclaration("Ni ght"),)}),
    ("layer name", {"layers": (LayerDeclaration("N" * 200),)}),
    ("excludes", {"layers": (LayerDeclaration("Night", excludes=frozenset({"a,b"})),)}),
    ("requires", {"layers": (LayerDeclaration("Night", requires=frozenset({""})),)}),
    (
        "requires",
        {"layers": (LayerDeclaration("Night", requires=frozenset(f"L{i}" for i in range(100))),)},
    ),
    ("group", {"layers": (LayerDeclaration("Night", group="a,b"),)}),
    ("after", {"layers": (LayerDeclaration("Night", after=frozenset({"Ni\x00ght"})),)}),
    ("layers", {"layers": tuple(LayerDeclaration(f"L{i}") for i in range(300))}),
    ("applied_epoch", {"applied_epoch": 2**64 - 1}),
    ("applied_epoch", {"applied_epoch": 10**15}),
    ("applied_epoch", {"applied_epoch": -1}),
    ("pending_epoch", {"pending_epoch": 2**64 - 1}),
    ("failed_epoch", {"failed_epoch": 10**15}),
    ("applied_manager_id", {"applied_manager_id": "m\n"}),
    ("applied_manager_id", {"applied_manager_id": LONG}),
    ("active_layers", {"active": ("Night\x00evil",)}),
    ("active_layers", {"active": ("Night", "Night")}),
    ("active_layers", {"active": tuple(f"L{i}" for i in range(300))}),
    ("error", {"error": LONG}),
    ("error", {"error": "bad\x1b[2J"}),
    ("vote_epoch", {"vote_epoch": 2**64 - 1}),
    ("vote_reason", {"vote_reason": "no\x00"}),
    ("vote_reason", {"vote_reason": LONG}),
    ("vote_manager_id", {"vote_manager_id": LONG}),
    ("hosted_nodes", {"hosted": ("guest",)}),
    ("hosted_nodes", {"hosted": tuple(f"/g{i}" for i in range(300))}),
]


def running_manager(**settings: Any) -> ManagerProtocol:
    manager = ManagerProtocol(
        0.0, ManagerSettings(recovery_window=1.0, unknown_layer_grace=0.0, **settings)
    )
    manager.receive_status(GOOD, 0.0)
    manager.tick(1.0)
    return manager


@pytest.mark.parametrize(
    ("field", "change"), BAD_REPORTS, ids=[f"{f}-{i}" for i, (f, _) in enumerate(BAD_REPORTS)]
)
def test_a_known_participants_bad_status_is_ignored_too(field: str, change: dict[str, Any]) -> None:
    """What a participant repeats from its last accepted status is not checked again: what
    it changes is (and a status under another node or incarnation is a stranger's)."""
    manager = running_manager()
    before = (manager.state, manager.registry(1.0).participants)
    actions = manager.receive_status(dataclasses.replace(GOOD, **change), 1.1)
    (rejected,) = actions
    assert isinstance(rejected, ReportRejected)
    assert any(field in problem for problem in rejected.problems), rejected.problems
    assert (manager.state, manager.registry(1.0).participants) == before


@pytest.mark.parametrize(
    ("field", "change"), BAD_REPORTS, ids=[f"{f}-{i}" for i, (f, _) in enumerate(BAD_REPORTS)]
)
def test_a_bad_status_is_ignored_and_named(field: str, change: dict[str, Any]) -> None:
    manager = running_manager()
    before = (manager.state, manager.registry(1.0).participants)
    bad = dataclasses.replace(GOOD, **{"node": "/b", "incarnation": "2", **change})
    actions = manager.receive_status(bad, 1.1)
    (rejected,) = actions
    assert isinstance(rejected, ReportRejected)
    assert any(field in problem for problem in rejected.problems), rejected.problems
    assert (manager.state, manager.registry(1.0).participants) == before
    manager.receive_status(bad, 1.2)
    assert manager.receive_status(bad, 1.3) == [], "logged once per sender and period"


@pytest.mark.parametrize("epoch", [2**64 - 1, 10**15, MAX_EPOCH + 1, MAX_EPOCH, MAX_EPOCH // 2 + 1])
def test_an_implausible_epoch_never_becomes_the_systems_epoch(epoch: int) -> None:
    for during_recovery in (True, False):
        manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0))
        liar = ParticipantReport("/liar", "1", (NIGHT,), applied_epoch=epoch, active=("Night",))
        if during_recovery:
            manager.receive_status(liar, 0.5)
        manager.receive_status(GOOD, 0.6)
        published = [a.state for a in manager.tick(1.0) if isinstance(a, PublishState)]
        if not during_recovery:
            published += [
                a.state for a in manager.receive_status(liar, 1.1) if isinstance(a, PublishState)
            ]
        assert [s.epoch for s in published] == [1]
        assert manager.live_nodes == ("/a",)


def test_a_report_far_above_a_known_epoch_is_not_adopted() -> None:
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0), LayerState(40))
    manager.receive_status(GOOD, 0.5)
    manager.tick(1.0)
    liar = ParticipantReport("/liar", "1", (NIGHT,), applied_epoch=41 + 10_001)
    (rejected,) = manager.receive_status(liar, 1.1)
    assert (
        isinstance(rejected, ReportRejected)
        and "above the manager's epoch 41" in rejected.problems[0]
    )
    honest = ParticipantReport("/late", "1", (NIGHT,), applied_epoch=60, active=("Night",))
    (state,) = [a.state for a in manager.receive_status(honest, 1.2) if isinstance(a, PublishState)]
    assert state.epoch == 61, "a plausible newer epoch is still adopted"


BAD_COMMANDS: list[tuple[str, dict[str, Any]]] = [
    ("activate", {"activate": ("Night\x00evil",)}),
    ("activate", {"activate": ("",)}),
    ("activate", {"activate": tuple(f"L{i}" for i in range(100_000))}),
    ("deactivate", {"deactivate": ("Ni ght",)}),
    ("deactivate", {"deactivate": ("N" * 500,)}),
    ("expect_nodes", {"expect_nodes": ("nobody",)}),
    ("expect_nodes", {"expect_nodes": tuple(f"/n{i}" for i in range(5000))}),
    ("expect_count", {"expect_count": -1}),
    ("timeout", {"timeout": float("nan")}),
    ("timeout", {"timeout": float("inf")}),
    ("timeout", {"timeout": -1.0}),
    ("timeout", {"timeout": 1e9}),
    ("requester", {"requester": "me\x00"}),
    ("reason", {"reason": LONG}),
]


@pytest.mark.parametrize(
    ("field", "change"), BAD_COMMANDS, ids=[f"{f}-{i}" for i, (f, _) in enumerate(BAD_COMMANDS)]
)
def test_a_bad_command_is_refused_naming_the_field_and_changes_nothing(
    field: str, change: dict[str, Any]
) -> None:
    manager = running_manager()
    before = manager.state
    actions = manager.receive_command(ActivationCommand(1, synchronous=True, **change), 1.1)
    (reply,) = actions
    assert isinstance(reply, Reply) and not reply.result.success
    assert f"invalid command: {field}" in reply.result.message or field in reply.result.message
    assert "nothing changed" in reply.result.message
    assert len(reply.result.message) < 1000, "the answer stays small"
    assert manager.state == before


def test_the_answer_to_many_unknown_layers_is_bounded() -> None:
    manager = running_manager()
    names = tuple(f"Unknown{i}" for i in range(256))
    (reply,) = manager.receive_command(ActivationCommand(1, activate=names), 1.1)
    assert isinstance(reply, Reply) and not reply.result.success
    assert "and 246 more" in reply.result.message and len(reply.result.message) < 600


BAD_STATES: list[tuple[str, dict[str, Any]]] = [
    ("epoch", {"epoch": 2**64 - 1}),
    ("epoch", {"epoch": 10**15}),
    ("active_layers", {"active": ("Night\x00evil",)}),
    ("active_layers", {"active": ("Night", "Night")}),
    ("active_layers", {"active": tuple(f"L{i}" for i in range(300))}),
    ("manager_id", {"manager_id": "m\x00"}),
    ("requester", {"requester": LONG}),
    ("reason", {"reason": "a\nb"}),
]


@pytest.mark.parametrize(
    ("field", "change"), BAD_STATES, ids=[f"{f}-{i}" for i, (f, _) in enumerate(BAD_STATES)]
)
def test_a_participant_ignores_a_bad_state(field: str, change: dict[str, Any]) -> None:
    participant = ParticipantProtocol("/p", "1", (NIGHT,))
    bad = dataclasses.replace(LayerState(5, ("Night",), manager_id="m"), **change)
    (rejected,) = participant.receive_state(bad, 1.0)
    assert isinstance(rejected, StateRejected)
    assert any(field in problem for problem in rejected.problems)
    good = LayerState(6, ("Night",), manager_id="m")
    assert ApplyState(good) in participant.receive_state(good, 1.1), "not poisoned by it"


@pytest.mark.parametrize("epoch", [2**64 - 1, 10**15])
def test_a_poisoned_state_file_is_refused_with_a_message(epoch: int) -> None:
    text = f'{{"epoch": {epoch}, "active": ["Night"]}}'
    with pytest.raises(StateFileError, match="beyond any epoch"):
        LayerState.from_json(text, "state.json")
    with pytest.raises(StateFileError, match="layer names"):
        LayerState.from_json('{"epoch": 3, "active": ["Night\\u0000evil"]}', "state.json")


def test_what_is_kept_about_node_names_stays_bounded() -> None:
    # Each status under a new name, hosting 256 names of 200 characters, then silence:
    # the manager kept every name's hosted nodes and retired incarnations forever.
    manager = running_manager()
    hosted = tuple(f"/h{i:03d}" + "x" * 195 for i in range(256))
    now = 1.0
    for i in range(200):
        for incarnation in ("1", "2"):  # a restart leaves a retired incarnation behind
            flood = ParticipantReport(f"/flood{i}", incarnation, (NIGHT,), hosted=hosted)
            manager.receive_status(flood, now)
        now += 0.01
        manager.receive_status(GOOD, now)
        manager.tick(now)
    manager.tick(now + 10.0)  # all silent: dropped
    kept = manager.settings.keep_dropped
    assert len(manager.dropped) == kept
    remembered = set(manager._hosted) | set(manager._retired)
    assert remembered <= {*manager.dropped, *manager.live_nodes}
    assert len(remembered) <= kept + len(manager.live_nodes)


def test_a_dropped_node_still_named_keeps_its_hosted_nodes() -> None:
    manager = running_manager()
    manager.receive_status(dataclasses.replace(GOOD, node="/b", hosted=("/b_child",)), 1.0)
    actions = manager.receive_command(ActivationCommand(1, ("Night",), synchronous=True), 1.0)
    assert not [a for a in actions if isinstance(a, Reply)], "waits for /a and /b"
    manager.receive_status(GOOD, 1.5)
    actions = manager.tick(1.0 + manager.settings.liveness_timeout + 0.5)
    manager.receive_status(GOOD, 4.6)
    actions += manager.tick(6.5)
    (reply,) = [a for a in actions if isinstance(a, Reply)]
    assert "/b_child (hosted by /b" in reply.result.message


def test_waiting_commands_are_capped_with_a_message_naming_the_cap() -> None:
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0, max_waiting_commands=3))
    manager.receive_status(GOOD, 0.0)
    # During recovery commands queue; afterwards synchronous ones wait for acknowledgements.
    for request_id in (1, 2):
        assert manager.receive_command(ActivationCommand(request_id, ("Night",)), 0.5) == []
    manager.tick(1.0)
    command = ActivationCommand(3, deactivate=("Night",), synchronous=True, timeout=5.0)
    assert not [a for a in manager.receive_command(command, 1.1) if isinstance(a, Reply)]
    for request_id in (4, 5):
        command = ActivationCommand(request_id, ("Night",), synchronous=True, timeout=5.0)
        assert not [a for a in manager.receive_command(command, 1.2) if isinstance(a, Reply)]
    assert manager.waiting_commands == 3
    (refused,) = manager.receive_command(ActivationCommand(6, ("Night",)), 1.3)
    assert isinstance(refused, Reply) and not refused.result.success
    assert "at most 3 (max_waiting_commands)" in refused.result.message
    assert "nothing changed" in refused.result.message
    manager.receive_status(GOOD, 6.0)
    manager.tick(7.0)  # the waiting ones answered (timed out): room again
    assert manager.waiting_commands == 0
    (accepted, *_) = manager.receive_command(ActivationCommand(7, deactivate=("Night",)), 7.1)
    assert not isinstance(accepted, Reply) or accepted.result.success
