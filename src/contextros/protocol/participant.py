"""A context node's side of the protocol, as a pure state machine.

It decides which manager states to apply (only ones newer than anything it has applied or
scheduled, so a reordered or duplicated message can never take the node back) and what to
report. A state deferred by a critical section is reported as pending, and acknowledged
(`applied_epoch`) only once the core has really applied it.
"""

from __future__ import annotations

from contextros.protocol.events import (
    ApplyState,
    ParticipantAction,
    ParticipantReport,
    PublishStatus,
)
from contextros.protocol.relations import LayerDeclaration
from contextros.protocol.state import LayerState

DEFAULT_HEARTBEAT_PERIOD = 0.25


class ParticipantProtocol:
    def __init__(
        self,
        node: str,
        incarnation: str,
        layers: tuple[LayerDeclaration, ...],
        heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD,
    ) -> None:
        self.node = node
        self.incarnation = incarnation
        self.layers = layers
        self.hosted: tuple[str, ...] = ()
        self.heartbeat_period = heartbeat_period
        self.applied_epoch = 0
        self.applied_manager_id = ""
        self.active: tuple[str, ...] = ()
        self.pending_epoch = 0
        self.failed_epoch = 0
        self.error = ""
        # Set by the adapter from the core: a critical section is open in this node.
        self.critical_section_open = False
        self._last_sent: float | None = None

    @property
    def newest_epoch(self) -> int:
        """The newest epoch applied, scheduled or refused: anything at or below is stale."""
        return max(self.applied_epoch, self.pending_epoch, self.failed_epoch)

    @property
    def deferring(self) -> bool:
        """A received state waits for a critical section to close."""
        return self.pending_epoch > self.applied_epoch

    @property
    def in_critical_section(self) -> bool:
        return self.critical_section_open or self.deferring

    def report(self, leaving: bool = False) -> ParticipantReport:
        return ParticipantReport(
            node=self.node,
            incarnation=self.incarnation,
            layers=self.layers,
            applied_epoch=self.applied_epoch,
            active=self.active,
            applied_manager_id=self.applied_manager_id,
            in_critical_section=self.in_critical_section,
            pending_epoch=self.pending_epoch if self.deferring else 0,
            failed_epoch=self.failed_epoch,
            error=self.error,
            leaving=leaving,
            hosted=self.hosted,
        )

    # -- events -----------------------------------------------------------------------------

    def announce(self, now: float) -> list[ParticipantAction]:
        return [self._send(now)]

    def receive_state(self, state: LayerState) -> list[ParticipantAction]:
        if state.epoch <= self.newest_epoch:
            return []
        return [ApplyState(state)]

    def applied(self, state: LayerState, now: float) -> list[ParticipantAction]:
        """The core applied `state` (at once, or when a critical section closed)."""
        if state.epoch <= self.applied_epoch:
            return []
        self.applied_epoch = state.epoch
        self.applied_manager_id = state.manager_id
        self.active = state.active
        return [self._send(now)]

    def deferred(self, state: LayerState, now: float) -> list[ParticipantAction]:
        """The core queued `state` behind an open critical section."""
        self.pending_epoch = max(self.pending_epoch, state.epoch)
        return [self._send(now)]

    def failed(self, state: LayerState, error: str, now: float) -> list[ParticipantAction]:
        """The core refused `state` (say, a local relation the manager did not know)."""
        self.failed_epoch = max(self.failed_epoch, state.epoch)
        self.error = f"epoch {state.epoch}: {error}"
        return [self._send(now)]

    def host(
        self, hosted: tuple[str, ...], layers: tuple[LayerDeclaration, ...], now: float
    ) -> list[ParticipantAction]:
        """Speak for these other nodes of the process, implementing these layers in all."""
        self.hosted = hosted
        self.layers = layers
        return [self._send(now)]

    def tick(self, now: float) -> list[ParticipantAction]:
        if self._last_sent is not None and now - self._last_sent < self.heartbeat_period:
            return []
        return [self._send(now)]

    def leave(self, now: float) -> list[ParticipantAction]:
        return [PublishStatus(self.report(leaving=True))]

    def _send(self, now: float) -> PublishStatus:
        self._last_sent = now
        return PublishStatus(self.report())
