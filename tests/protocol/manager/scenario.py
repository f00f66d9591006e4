"""A manager driven by hand on a fake clock, with participants that apply what it publishes:
the shared setting of the tests of each part of `contextros.protocol.manager`."""

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
    ParticipantReport,
    PublishState,
    Reply,
)

SETTINGS = ManagerSettings(
    liveness_timeout=2.0,
    default_timeout=5.0,
    recovery_window=1.0,
    unknown_layer_grace=0.0,
    memoryless_epoch_gap=1,  # the gap has its own test (test_recovery.py)
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
