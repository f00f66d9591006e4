"""Managers that break a guarantee on purpose: the simulation and the explorer must catch
each (their checks can fail)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerState,
    ManagerAction,
    ManagerMemory,
    ManagerProtocol,
    ManagerSettings,
    PublishState,
    Reply,
)
from contextros.protocol.manager import Key


class ReusesEpochs(ManagerProtocol):
    """Publishes every new configuration under the epoch it has already."""

    def _publish(
        self,
        active: tuple[str, ...],
        requester: str,
        reason: str,
        now: float,
        above: int,
        explicit: tuple[str, ...] | None = None,
    ) -> PublishState:
        epoch = self._state.epoch
        published = super()._publish(active, requester, reason, now, above, explicit)
        if not epoch:
            return published
        self._state = dataclasses.replace(self._state, epoch=epoch)
        return PublishState(self._state)


class ClaimsEveryNode(ManagerProtocol):
    """Answers a synchronous command at once, claiming every live node applied it."""

    def receive_command(
        self, command: ActivationCommand, now: float, received: float | None = None
    ) -> list[ManagerAction]:
        actions = super().receive_command(command, now, received)
        if not command.synchronous:
            return actions
        self._pending.clear()
        result = ActivationResult(True, "", self._state.epoch + 1, (), self.live_nodes)
        return [*actions, Reply(command.request_id, result)]


class ForgetsProposals(ManagerProtocol):
    """Restarts as before issue 24 (item 1): the epochs it proposed are forgotten, so a
    vote cut by the crash has its epoch reused for another layer set."""

    def __init__(
        self,
        now: float,
        settings: ManagerSettings | None = None,
        saved_state: LayerState | ManagerMemory | None = None,
    ) -> None:
        super().__init__(now, settings, saved_state)
        self._epoch_floor = 0


class ForgetsParticipants(ManagerProtocol):
    """Restarts as before issue 24 (item 2): the nodes it knew live are forgotten, so its
    first synchronous answer can claim success from the nodes heard so far."""

    def __init__(
        self,
        now: float,
        settings: ManagerSettings | None = None,
        saved_state: LayerState | ManagerMemory | None = None,
    ) -> None:
        super().__init__(now, settings, saved_state)
        self._participants.clear()
        self._hosted.clear()


class WaitsForOneNode(ManagerProtocol):
    """Takes a synchronous activation for done once one node applied it."""

    def _settle_pending(
        self, now: float, examine: Iterable[Key] | None = None
    ) -> list[ManagerAction]:
        for pending in self._pending:
            if pending.acknowledged:
                pending.waiting.clear()
        return super()._settle_pending(now, examine)
