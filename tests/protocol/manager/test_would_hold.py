"""`ManagerProtocol.would_hold`: whether a command would wait inside the protocol (recovery,
an open atomic vote, a layer not known yet within the grace period) instead of being
decided now. The manager node keeps such commands itself while layers drive ROS."""

from __future__ import annotations

from contextros.protocol import (
    ActivationCommand,
    LayerDeclaration,
    ManagerProtocol,
    ManagerSettings,
    ParticipantReport,
    PublishProposal,
    PublishState,
    Reply,
)

LAYERS = (LayerDeclaration("Night"), LayerDeclaration("Slow"))
SETTINGS = ManagerSettings(recovery_window=1.0, unknown_layer_grace=2.0, default_timeout=2.0)


def report(
    node: str, applied: int = 0, layers: tuple[LayerDeclaration, ...] = LAYERS, **extra: object
) -> ParticipantReport:
    return ParticipantReport(node, "1", layers, applied_epoch=applied, **extra)  # type: ignore[arg-type]


def running() -> ManagerProtocol:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    manager.tick(1.0)  # recovery over: epoch 1, grace until 3.0
    manager.receive_status(report("/a", 1), 1.0)
    return manager


def test_while_recovering_every_valid_command_would_wait() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    command = ActivationCommand(1, activate=("Night",))
    assert manager.would_hold(command, 0.5)
    assert manager.receive_command(command, 0.5) == [], "and the protocol does hold it"
    assert not manager.would_hold(ActivationCommand(2, activate=("Night\x00",)), 0.5), (
        "an invalid command is refused at once"
    )


def test_a_known_layer_is_decided_at_once() -> None:
    manager = running()
    command = ActivationCommand(1, activate=("Night",))
    assert not manager.would_hold(command, 1.1)
    assert any(isinstance(a, PublishState) for a in manager.receive_command(command, 1.1))


def test_an_unknown_layer_waits_only_within_the_grace_period() -> None:
    manager = running()
    command = ActivationCommand(1, activate=("Flight",))
    assert manager.would_hold(command, 1.5)
    assert manager.receive_command(command, 1.5) == [], "and the protocol does hold it"
    assert not manager.would_hold(ActivationCommand(2, activate=("Flight",)), 3.0)
    # A participant implementing it arrives: decided at once.
    manager.receive_status(report("/b", 1, (LayerDeclaration("Flight"),)), 1.6)
    assert not manager.would_hold(ActivationCommand(3, activate=("Flight",)), 1.6)


def test_a_refused_command_is_not_held() -> None:
    manager = running()
    both = ActivationCommand(1, activate=("Night",), deactivate=("Night",))
    assert not manager.would_hold(both, 1.5)
    assert isinstance(manager.receive_command(both, 1.5)[0], Reply)


def test_every_command_waits_while_an_atomic_vote_is_open() -> None:
    manager = running()
    vote = ActivationCommand(1, activate=("Night",), atomic=True)
    assert not manager.would_hold(vote, 1.1)
    assert any(isinstance(a, PublishProposal) for a in manager.receive_command(vote, 1.1))
    later = ActivationCommand(2, activate=("Slow",))
    assert manager.would_hold(later, 1.2)
    assert manager.receive_command(later, 1.2) == [], "and the protocol does hold it"
    manager.receive_status(report("/a", 1, vote_epoch=2, vote_yes=True), 1.3)  # commit
    assert not manager.would_hold(ActivationCommand(3, activate=("Slow",)), 1.3)


def test_asking_changes_nothing() -> None:
    manager = running()
    before = (manager.state, manager.registry(1.5))
    for command in (
        ActivationCommand(1, activate=("Night",)),
        ActivationCommand(2, activate=("Flight",)),
        ActivationCommand(3, activate=("Night",), atomic=True),
    ):
        manager.would_hold(command, 1.5)
    assert (manager.state, manager.registry(1.5)) == before
