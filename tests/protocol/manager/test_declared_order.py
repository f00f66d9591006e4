"""The manager composes the active set in the order `after` declares (issue 11, part 4):
activating [Rubble, Flight, Flooded] with `Rubble after Flooded` must not hide Rubble."""

from __future__ import annotations

from contextros.protocol import (
    ActivationCommand,
    LayerDeclaration,
    ManagerProtocol,
    ManagerSettings,
    ParticipantReport,
    PublishState,
    Reply,
)
from contextros.protocol.relations import declared_order, merge_declarations

SETTINGS = ManagerSettings(recovery_window=1.0, unknown_layer_grace=0.0)
RUBBLE = LayerDeclaration("Rubble", after=frozenset({"Flooded"}))
FLIGHT = LayerDeclaration("Flight")
FLOODED = LayerDeclaration("Flooded")


def manager(*layers: LayerDeclaration) -> ManagerProtocol:
    protocol = ManagerProtocol(0.0, SETTINGS)
    report = ParticipantReport(node="/a", incarnation="1", layers=layers)
    protocol.receive_status(report, 0.0)
    protocol.tick(2.0)
    return protocol


def activate(protocol: ManagerProtocol, *layers: str) -> tuple[tuple[str, ...], str, bool]:
    actions = protocol.receive_command(ActivationCommand(1, activate=layers), 2.0)
    published = [a.state.active for a in actions if isinstance(a, PublishState)]
    reply = next(a.result for a in actions if isinstance(a, Reply))
    return (published[-1] if published else ()), reply.message, reply.success


def test_the_requested_order_is_corrected_to_the_declared_one() -> None:
    active, message, success = activate(
        manager(RUBBLE, FLIGHT, FLOODED), "Rubble", "Flight", "Flooded"
    )
    assert success
    assert active == ("Flight", "Flooded", "Rubble"), "Rubble outermost, as declared"
    assert "composed as declared: Rubble after Flooded" in message


def test_an_order_that_agrees_is_kept_and_not_commented() -> None:
    active, message, _ = activate(manager(RUBBLE, FLIGHT, FLOODED), "Flooded", "Flight", "Rubble")
    assert active == ("Flooded", "Flight", "Rubble")
    assert "composed as declared" not in message


def test_a_layer_activated_later_still_goes_where_it_is_declared() -> None:
    protocol = manager(RUBBLE, FLIGHT, FLOODED)
    activate(protocol, "Rubble")
    active, message, _ = activate(protocol, "Flooded")
    assert active == ("Flooded", "Rubble")
    assert "Rubble after Flooded" in message


def test_declarations_from_different_nodes_are_merged() -> None:
    other_node = LayerDeclaration("Flight", after=frozenset({"Rubble"}))
    merged = merge_declarations([RUBBLE, FLIGHT, FLOODED, other_node])
    order = declared_order(["Flight", "Rubble", "Flooded"], merged)
    assert order.layers == ("Flooded", "Rubble", "Flight")
    assert set(order.moved) == {("Flight", "Rubble"), ("Rubble", "Flooded")}


def test_a_cycle_of_after_declarations_refuses_the_command() -> None:
    a = LayerDeclaration("A", after=frozenset({"B"}))
    b = LayerDeclaration("B", after=frozenset({"A"}))
    protocol = manager(a, b)
    active, message, success = activate(protocol, "A", "B")
    assert not success and active == ()
    assert "'after' orders of A, B form a cycle" in message
    assert "nothing changed" in message
