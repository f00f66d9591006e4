"""The manager's state, in one place, and the parts of it every other part uses.

`ManagerProtocol` (protocol.py) is this state plus one mixin per concern, each in a module
named after it: registry.py (who is live, their declarations, liveness), command_queue.py
(validating and executing commands, holding them while they cannot be decided yet),
acknowledgements.py (synchronous activations waiting for their nodes), atomic_votes.py
(the two-phase atomic activation) and recovery.py (a (re)started manager's first state);
records.py holds the plain records they share. A part calls another only through the
methods declared abstract here.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Iterable
from dataclasses import replace

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    ParticipantReport,
    PublishHeartbeat,
    PublishState,
)
from contextros.protocol.manager.records import (
    Key,
    ParticipantRecord,
    PendingActivation,
    Transaction,
)
from contextros.protocol.manager.settings import ManagerSettings
from contextros.protocol.relations import DeclaredOrder, LayerDeclaration, Switched, explicit_roots
from contextros.protocol.state import INITIAL_STATE, LayerState, ManagerMemory

# The message of a command that leaves the configuration as it was (clients show it as is).
NO_CHANGE = "no change"


class ManagerBase(ABC):
    """Everything the manager keeps, and publishing a new state."""

    def __init__(
        self,
        now: float,
        settings: ManagerSettings | None = None,
        saved_state: LayerState | ManagerMemory | None = None,
    ) -> None:
        self.settings = settings or ManagerSettings()
        memory = saved_state if isinstance(saved_state, ManagerMemory) else None
        saved = saved_state.state if isinstance(saved_state, ManagerMemory) else saved_state
        self._state: LayerState = saved or INITIAL_STATE
        # The layers of the state asked for explicitly, in its order; the others are there
        # because one of these implies them (a state file from before `implies`: all asked).
        explicit = memory.explicit if memory is not None else None
        self._explicit: tuple[str, ...] = self._state.active if explicit is None else explicit
        self._participants: dict[Key, ParticipantRecord] = {}
        # Incarnations replaced by a newer one under the same name (a restart); hearing one
        # again means two live processes share the name.
        self._retired: dict[str, set[str]] = {}
        # The nodes each participant speaks for, kept past a drop to name them in answers.
        self._hosted: dict[str, tuple[str, ...]] = {}
        self._pending: list[PendingActivation] = []
        self._queued: list[tuple[ActivationCommand, float]] = []
        self._order_cache: tuple[ActivationCommand, int, DeclaredOrder, Switched] | None = None
        self._declarations_cache: dict[str, LayerDeclaration] | None = None
        # Commands naming layers not known yet, held during the grace period after recovery.
        self._held: list[tuple[ActivationCommand, float]] = []
        self._dropped: deque[str] = deque(maxlen=self.settings.keep_dropped)
        self._recovering_until: float | None = now + self.settings.recovery_window
        self._recovery_limit = now + 3 * self.settings.recovery_window
        self._grace_until = self._recovery_limit + self.settings.unknown_layer_grace
        # Until a client decides something, the newest configuration a participant reports
        # is the truth (the manager restarted without a state file, or with an older one).
        self._decided_here = False
        self._next_beat = now
        self._repeats: list[float] = []
        self._rejections_logged: dict[str, float] = {}
        # Liveness (registry.py): the heartbeat period announced to the participants, the
        # longer bound of a longer period announced before (until when it holds), and a
        # time no participant was heard before (no need to look for silent ones until then).
        self._status_period = self.settings.status_period
        self._earlier_bound = (0.0, 0.0)
        self._oldest_heard = now
        # The open atomic activation, if any; commands wait behind it. Every proposed epoch
        # is used once: an aborted one is skipped, so a vote always names one proposal.
        self._transaction: Transaction | None = None
        self._behind_transaction: list[tuple[ActivationCommand, float]] = []
        self._epoch_floor = 0
        self._memoryless = saved is None
        if memory is not None:
            self._epoch_floor = memory.proposed_epoch
            # The nodes live before the restart are awaited as live ones (a synchronous
            # answer waits for them) until they report or the liveness bound drops them.
            for known in memory.participants:
                report = ParticipantReport(known.node, known.incarnation, hosted=known.hosted)
                key = (known.node, known.incarnation)
                self._participants[key] = ParticipantRecord(report, now, presumed=True)
                self._hosted[known.node] = known.hosted

    def memory(self) -> ManagerMemory:
        """What a state file keeps (see `ManagerMemory`): the adapter saves it whenever it
        differs from the last saved one, before publishing a state or a proposal."""
        return ManagerMemory(
            state=self._state,
            proposed_epoch=max(self._epoch_floor, self._state.epoch),
            # In the order they joined (sorting them at every join made a fleet's start-up
            # quadratic: 10,000 joins, each a write of the state file).
            participants=tuple(record.known() for record in self._participants.values()),
            explicit=self._explicit,
        )

    @property
    def state(self) -> LayerState:
        return self._state

    @property
    def explicit(self) -> tuple[str, ...]:
        """The active layers asked for explicitly (the others are implied by these)."""
        return self._explicit

    @property
    def recovering(self) -> bool:
        return self._recovering_until is not None

    def _publish(
        self,
        active: tuple[str, ...],
        requester: str,
        reason: str,
        now: float,
        above: int,
        explicit: tuple[str, ...] | None = None,
    ) -> PublishState:
        """Publish `active`; `explicit`: which of them were asked for (None: the current
        state's, if it is the same configuration, else those no other active layer implies)."""
        if explicit is None:
            if tuple(active) == self._state.active:
                explicit = self._explicit
            else:
                explicit = explicit_roots(active, self.declarations())
        self._explicit = tuple(name for name in explicit if name in active)
        self._state = LayerState(
            epoch=max(above, self._state.epoch, self._epoch_floor) + 1,
            active=tuple(active),
            requester=requester,
            reason=reason,
            stamp=now,
            manager_id=self.settings.manager_id,
            status_period=self._status_period,
        )
        # Repeat it on the best-effort heartbeat shortly after: on a lossy link the reliable
        # state can wait seconds behind retransmissions, a repeat does not.
        self._repeats = [now + delay for delay in self.settings.repeats]
        return PublishState(self._state)

    def _heartbeat(self, now: float) -> list[ManagerAction]:
        beat_due = now >= self._next_beat
        repeat_due = bool(self._repeats) and now >= self._repeats[0]
        if not (beat_due or repeat_due):
            return []
        self._repeats = [t for t in self._repeats if t > now]
        if not beat_due and not self._someone_lags():
            return []  # every node has the state: a repeat would only load them
        self._next_beat = now + self.settings.heartbeat_period
        if self.recovering:
            beat = LayerState(epoch=0, reason="recovering", manager_id=self.settings.manager_id)
        elif self._state.manager_id:
            beat = self._state
        else:  # nothing published yet: still with its id, so another manager hears this one
            beat = replace(self._state, manager_id=self.settings.manager_id)
        if beat.status_period != self._status_period:  # it carries the current period
            beat = replace(beat, status_period=self._status_period)
        return [PublishHeartbeat(beat)]

    def _someone_lags(self) -> bool:
        return any(r.report.applied_epoch < self._state.epoch for r in self._participants.values())

    def _deadline(self, command: ActivationCommand, received: float) -> float:
        """When the caller gives up on `command`: its timeout (or the manager's default)
        after its arrival. A command not decided by then is refused, never executed."""
        timeout = command.timeout if command.timeout > 0 else self.settings.default_timeout
        return received + timeout

    def _result(self, success: bool, message: str) -> ActivationResult:
        return ActivationResult(success, message, self._state.epoch, self._state.active)

    # -- provided by the parts --------------------------------------------------------------

    @abstractmethod
    def declarations(self) -> dict[str, LayerDeclaration]: ...

    @abstractmethod
    def conflicts(self) -> tuple[str, ...]: ...

    @abstractmethod
    def _execute(
        self, command: ActivationCommand, now: float, received: float
    ) -> list[ManagerAction]: ...

    @abstractmethod
    def _settle_pending(
        self, now: float, examine: Iterable[Key] | None = None
    ) -> list[ManagerAction]: ...

    @abstractmethod
    def _await_rejoined(self, key: Key) -> None: ...

    @abstractmethod
    def _propose(
        self,
        command: ActivationCommand,
        active: tuple[str, ...],
        now: float,
        received: float,
        explicit: tuple[str, ...] | None = None,
    ) -> list[ManagerAction]: ...

    @abstractmethod
    def _abort(self, now: float, reasons: dict[str, str]) -> list[ManagerAction]: ...
