"""Atomic activation (issue 10): every target votes, then the same epoch is committed
everywhere; a veto, a timeout or a lost target aborts with nothing changed anywhere, and
the answer names who and why."""

from __future__ import annotations

from collections.abc import Sequence

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerDeclaration,
    ManagerAction,
    ManagerProtocol,
    ManagerSettings,
    ParticipantReport,
    PublishProposal,
    PublishState,
    Reply,
)

LAYERS = (LayerDeclaration("Indoor", group="location"), LayerDeclaration("Night"))
SETTINGS = ManagerSettings(recovery_window=1.0, unknown_layer_grace=0.0, default_timeout=2.0)


def report(node: str, applied: int = 1, **extra: object) -> ParticipantReport:
    return ParticipantReport(node, "1", LAYERS, applied_epoch=applied, **extra)  # type: ignore[arg-type]


def vote(node: str, epoch: int, yes: bool = True, why: str = "") -> ParticipantReport:
    return report(node, vote_epoch=epoch, vote_yes=yes, vote_reason=why)


def replies(actions: Sequence[ManagerAction]) -> dict[int, ActivationResult]:
    return {a.request_id: a.result for a in actions if isinstance(a, Reply)}


def proposals(actions: Sequence[ManagerAction]) -> list[int]:
    return [a.state.epoch for a in actions if isinstance(a, PublishProposal)]


def states(actions: Sequence[ManagerAction]) -> list[int]:
    return [a.state.epoch for a in actions if isinstance(a, PublishState)]


def running(nodes: Sequence[str] = ("/a", "/b")) -> ManagerProtocol:
    manager = ManagerProtocol(0.0, SETTINGS)
    for node in nodes:
        manager.receive_status(report(node, 0), 0.0)
    manager.tick(1.0)
    for node in nodes:
        manager.receive_status(report(node, 1), 1.0)
    return manager


def atomic(
    manager: ManagerProtocol, request_id: int, now: float, **fields: object
) -> list[ManagerAction]:
    command = ActivationCommand(request_id, atomic=True, **fields)  # type: ignore[arg-type]
    return manager.receive_command(command, now)


def test_all_yes_commits_the_proposed_epoch_and_waits_for_every_acknowledgement() -> None:
    manager = running()
    actions = atomic(manager, 1, 1.1, activate=("Night",))
    assert proposals(actions) == [2] and states(actions) == []
    assert manager.state.epoch == 1, "nothing changes while voting"
    assert states(manager.receive_status(vote("/a", 2), 1.2)) == []
    commit = manager.receive_status(vote("/b", 2), 1.3)
    assert states(commit) == [2], "the same epoch is committed"
    assert manager.state.active == ("Night",)
    manager.receive_status(report("/a", 2, vote_epoch=2, vote_yes=True), 1.4)
    result = replies(manager.receive_status(report("/b", 2, vote_epoch=2, vote_yes=True), 1.5))[1]
    assert result.success and result.epoch == 2 and result.acknowledged == ("/a", "/b")


def test_a_veto_aborts_with_nothing_changed_and_names_who_and_why() -> None:
    manager = running()
    atomic(manager, 1, 1.1, activate=("Night",))
    manager.receive_status(vote("/a", 2), 1.2)
    actions = manager.receive_status(vote("/b", 2, yes=False, why="in a critical section"), 1.3)
    result = replies(actions)[1]
    assert states(actions) == [] and manager.state.epoch == 1 and manager.state.active == ()
    assert not result.success and result.not_acknowledged == ("/b",)
    assert result.message == (
        "atomic activation of epoch 2 aborted, nothing changed: /b vetoed: in a critical section"
    )
    # The aborted epoch is never used: the next state is epoch 3.
    assert states(manager.receive_command(ActivationCommand(2, activate=("Night",)), 1.4)) == [3]


def test_a_timeout_or_a_lost_target_aborts() -> None:
    manager = running()
    atomic(manager, 1, 1.1, activate=("Night",), timeout=0.5)
    manager.receive_status(vote("/a", 2), 1.2)
    result = replies(manager.tick(1.65))[1]
    assert not result.success and "/b did not vote within 0.5 s" in result.message
    atomic(manager, 2, 1.7, activate=("Night",))
    manager.receive_status(vote("/a", 3), 1.8)
    result = replies(manager.receive_status(report("/b", leaving=True), 1.9))[2]
    assert not result.success and "/b lost before the commit (left)" in result.message
    assert manager.state.epoch == 1


def test_a_node_that_never_votes_holds_the_system_at_most_max_vote_time() -> None:
    manager = running()
    atomic(manager, 1, 1.1, activate=("Night",), timeout=3600.0)
    manager.receive_status(vote("/a", 2), 1.2)
    outcome: dict[int, ActivationResult] = {}
    now = 1.2
    while not outcome and now < 100.0:
        now += 0.5
        actions = manager.receive_status(report("/a", 1, vote_epoch=2, vote_yes=True), now)
        actions += manager.receive_status(report("/b", 1), now)  # alive, never voting
        outcome = replies([*actions, *manager.tick(now)])
    assert not outcome[1].success and "/b did not vote within 60 s" in outcome[1].message
    assert 61.0 <= now <= 62.0 and manager.state.epoch == 1


def test_other_commands_wait_for_the_outcome_of_the_vote() -> None:
    manager = running()
    assert proposals(atomic(manager, 1, 1.1, activate=("Night",))) == [2]
    assert manager.receive_command(ActivationCommand(2, activate=("Indoor",)), 1.2) == []
    actions = manager.receive_status(vote("/a", 2), 1.3) + manager.receive_status(
        vote("/b", 2), 1.3
    )
    assert states(actions) == [2, 3], "committed, then the waiting command"
    assert replies(actions)[2].success and manager.state.active == ("Night", "Indoor")


def test_the_proposal_is_repeated_while_the_vote_is_open() -> None:
    manager = running()
    atomic(manager, 1, 1.1, activate=("Night",))
    assert proposals(manager.tick(1.15)) == [2]
    manager.receive_status(vote("/a", 2), 1.2)
    manager.receive_status(vote("/b", 2), 1.2)
    assert proposals(manager.tick(1.25)) == []


def test_expected_nodes_must_be_live_to_start() -> None:
    manager = running()
    result = replies(atomic(manager, 1, 1.1, activate=("Night",), expect_nodes=("/arm",)))[1]
    assert not result.success and "expected node /arm is not live" in result.message
    assert result.not_acknowledged == ("/arm",) and manager.state.epoch == 1
