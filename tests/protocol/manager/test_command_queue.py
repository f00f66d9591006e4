"""Commands: validated against the live declarations, composed as the core's `switch`,
held while they cannot be decided yet."""

from __future__ import annotations

import pytest

from contextros.protocol import (
    ActivationCommand,
    LayerDeclaration,
    ManagerProtocol,
    ManagerSettings,
)
from tests.protocol.manager.scenario import (
    SETTINGS,
    System,
    command,
    replies,
    report,
    states,
)


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


def test_unknown_layer_is_rejected_by_name_and_changes_nothing() -> None:
    system = System()
    system.command(1, activate=("Indoor",))
    actions = system.command(2, activate=("Night", "Underwater"), synchronous=True)
    assert states(actions) == []
    result = replies(actions)[2]
    assert not result.success
    assert "'Underwater'" in result.message and "nothing changed" in result.message
    assert system.manager.state.epoch == 2 and system.manager.state.active == ("Indoor",)


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
