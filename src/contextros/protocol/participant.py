"""A context node's side of the protocol, as a pure state machine.

It decides which manager states to apply (only ones newer than anything it has applied or
scheduled, so a reordered or duplicated message can never take the node back) and what to
report. A state deferred by a critical section is reported as pending, and acknowledged
(`applied_epoch`) only once the core has really applied it.

On a lossy link every report may be lost: a new report is repeated shortly after it was
first sent (`repeats`) once the link has shown loss (a gap in the manager's heartbeat)
in the last `LOSS_MEMORY` seconds, and the heartbeat repeats it anyway. The manager's own heartbeat
tells the participant it is still connected; silent for `manager_timeout`, the node knows
it is cut off (`ManagerLost`) and may fall back to a safe configuration.
"""

from __future__ import annotations

from contextros.protocol.events import (
    ApplyState,
    ManagerFound,
    ManagerLost,
    ParticipantAction,
    ParticipantReport,
    PublishStatus,
    StateRejected,
)
from contextros.protocol.relations import (
    LayerDeclaration,
    merge_declarations,
    relation_violations,
)
from contextros.protocol.state import LayerState
from contextros.protocol.validation import state_problems

DEFAULT_HEARTBEAT_PERIOD = 0.25
DEFAULT_MANAGER_TIMEOUT = 3.0  # the manager's liveness bound, the same in both directions
# The leaving report is best effort like every report: adapters send it again this much
# later, which also lets the first copy leave the process before its writer is destroyed.
LEAVE_REPEAT_AFTER = 0.05
# Reports are repeated shortly after a change only while the link shows loss: this long
# after the manager was last heard late (more than 1.6 heartbeat periods after the message
# before). On a clean link the repeats only loaded the manager (sync at N=64: 8.7 -> 14.3 ms).
LOSS_MEMORY = 30.0
DEFAULT_REPEATS = (0.05, 0.15)
# The managers whose newest proposal voted on a participant remembers (a restart is a new
# manager; a late proposal of an older one is over).
VOTED_MANAGERS = 8


class ParticipantProtocol:
    def __init__(
        self,
        node: str,
        incarnation: str,
        layers: tuple[LayerDeclaration, ...],
        heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD,
        manager_timeout: float = DEFAULT_MANAGER_TIMEOUT,
        repeats: tuple[float, ...] = DEFAULT_REPEATS,
    ) -> None:
        self.node = node
        self.incarnation = incarnation
        self.layers = layers
        self.hosted: tuple[str, ...] = ()
        self.heartbeat_period = heartbeat_period
        # This node's own heartbeat period: `heartbeat_period`, or longer if the manager
        # asks for it (`status_period` with its states and heartbeats: many participants).
        self.status_period = heartbeat_period
        self.manager_timeout = manager_timeout
        self.repeats = repeats
        self.applied_epoch = 0
        self.applied_manager_id = ""
        self.active: tuple[str, ...] = ()
        self.pending_epoch = 0
        self.failed_epoch = 0
        self.error = ""
        # Set by the adapter from the core: a critical section is open in this node.
        self.critical_section_open = False
        self._last_sent: float | None = None
        self._repeat_at: list[float] = []
        # Manager liveness: when it was last heard (or when we started listening), whether
        # we told the node it is lost, and which manager we heard last.
        self._manager_heard: float | None = None
        self._last_message: float | None = None  # the manager's last message, if any
        self._loss_seen: float | None = None  # when it was last heard late
        self.manager_lost = False
        self.manager_id = ""
        # The last vote on an atomic activation (a proposal), repeated in every report.
        self.vote_epoch = 0
        self.vote_yes = False
        self.vote_reason = ""
        self.vote_manager_id = ""
        # The newest epoch voted on per manager (the last few managers): a late copy of an
        # older proposal is over, not voted on (nor its vetoes asked) again.
        self._voted: dict[str, int] = {}

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

    @property
    def next_repeat(self) -> float | None:
        """When a repeat of the last report is due (the adapter wakes up for it), if any."""
        return self._repeat_at[0] if self._repeat_at else None

    @property
    def next_tick(self) -> float | None:
        """When `tick` next has something to do (a heartbeat, a repeat, the manager's
        liveness bound), if known: before that it returns nothing (the C++ participant's
        wait loop sleeps until then; the simulation wakes a node only then)."""
        if self._last_sent is None or self._manager_heard is None:
            return None
        due = self._last_sent + 0.8 * self.status_period
        if self._repeat_at:
            due = min(due, self._repeat_at[0])
        if not self.manager_lost:
            due = min(due, self._manager_heard + self.manager_timeout + 1e-6)
        return due

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
            manager_lost=self.manager_lost,
            vote_epoch=self.vote_epoch,
            vote_yes=self.vote_yes,
            vote_reason=self.vote_reason,
            vote_manager_id=self.vote_manager_id,
        )

    def continue_from(self, previous: ParticipantProtocol) -> None:
        """Carry on for the process from `previous`, the participant this one replaces (its
        node went, another node of the process carries the participant now). The process's
        layers are what `previous` applied: without its epoch a reordered older state could
        take them back, and a recovering manager without memory would hear "epoch 0" from
        this process. Call it before `announce`. A switch `previous` deferred is not carried
        (its acknowledgement went with it): the manager's states bring it again."""
        self.applied_epoch = previous.applied_epoch
        self.applied_manager_id = previous.applied_manager_id
        self.active = previous.active
        self.failed_epoch = previous.failed_epoch
        self.error = previous.error
        self.manager_id = previous.manager_id
        self.manager_lost = previous.manager_lost
        self._manager_heard = previous._manager_heard
        self.status_period = previous.status_period

    # -- events -----------------------------------------------------------------------------

    def announce(self, now: float) -> list[ParticipantAction]:
        if self._manager_heard is None:
            self._manager_heard = now  # the manager-lost clock starts with the node
        return [self._send(now, repeat=True, always=True)]

    def receive_state(self, state: LayerState, now: float | None = None) -> list[ParticipantAction]:
        """A state from the manager (reliable topic or heartbeat): apply it if newer; its
        `status_period` is this node's heartbeat period from now on (0: its own)."""
        problems = state_problems(state)
        if problems:
            return [StateRejected(tuple(problems[:5]))]
        if now is not None:
            self.status_period = max(self.heartbeat_period, _period(state.status_period))
        actions = self._heard_manager(state.manager_id, now)
        if state.epoch == 0 or state.epoch <= self.newest_epoch:
            return actions
        return [*actions, ApplyState(state)]

    def wants_vote(self, proposal: LayerState) -> bool:
        """Whether `receive_proposal` would vote on `proposal` (it is new, valid and not
        voted on yet): the adapter asks the application's vetoes once per proposal."""
        newest_voted = self._voted.get(proposal.manager_id, 0)
        fresh = proposal.epoch > max(self.newest_epoch, newest_voted)
        return fresh and not state_problems(proposal)

    def receive_proposal(
        self, proposal: LayerState, now: float, veto: str = "", vote: bool = True
    ) -> list[ParticipantAction]:
        """An atomic activation asks whether this node can apply `proposal`: vote once.

        Yes means: no critical section is open or deferring a switch now, the proposed
        layers break none of the relations this node declares, and `veto` (the
        application's own answer, from the adapter) is empty. A vote changes nothing: the
        node switches only when the manager commits, with a state of that epoch.
        `vote=False`: the proposal only shows the manager is alive (the adapter is still
        asking the application's vetoes about it).
        """
        problems = state_problems(proposal)
        if problems:
            return [StateRejected(tuple(problems[:5]))]
        actions = self._heard_manager(proposal.manager_id, now)
        if not vote or not self.wants_vote(proposal):
            return actions  # stale, or already voted (every report repeats the vote)
        reasons = [veto] if veto else []
        if self.in_critical_section:
            reasons.append("in a critical section")
        reasons += relation_violations(proposal.active, merge_declarations(self.layers))
        self.vote_epoch = proposal.epoch
        self.vote_manager_id = proposal.manager_id
        self._voted.pop(proposal.manager_id, None)
        self._voted[proposal.manager_id] = proposal.epoch
        while len(self._voted) > VOTED_MANAGERS:
            del self._voted[next(iter(self._voted))]
        self.vote_yes = not reasons
        self.vote_reason = _printable("; ".join(reasons))
        return [*actions, self._send(now, repeat=True)]

    def applied(self, state: LayerState, now: float) -> list[ParticipantAction]:
        """The core applied `state` (at once, or when a critical section closed)."""
        if state.epoch <= self.applied_epoch:
            return []
        self.applied_epoch = state.epoch
        self.applied_manager_id = state.manager_id
        self.active = state.active
        return [self._send(now, repeat=True)]

    def deferred(self, state: LayerState, now: float) -> list[ParticipantAction]:
        """The core queued `state` behind an open critical section."""
        self.pending_epoch = max(self.pending_epoch, state.epoch)
        return [self._send(now, repeat=True)]

    def failed(self, state: LayerState, error: str, now: float) -> list[ParticipantAction]:
        """The core refused `state` (say, a local relation the manager did not know)."""
        self.failed_epoch = max(self.failed_epoch, state.epoch)
        self.error = _printable(f"epoch {state.epoch}: {error}")
        return [self._send(now, repeat=True)]

    def host(
        self, hosted: tuple[str, ...], layers: tuple[LayerDeclaration, ...], now: float
    ) -> list[ParticipantAction]:
        """Speak for these other nodes of the process, implementing these layers in all."""
        self.hosted = hosted
        self.layers = layers
        return [self._send(now, repeat=True)]

    def tick(self, now: float) -> list[ParticipantAction]:
        actions: list[ParticipantAction] = []
        if self._manager_heard is None:
            self._manager_heard = now
        silent = now - self._manager_heard
        if not self.manager_lost and silent > self.manager_timeout:
            self.manager_lost = True
            self._loss_seen = now
            self.status_period = self.heartbeat_period  # whichever manager comes next
            actions.append(ManagerLost(silent))
        due_repeat = bool(self._repeat_at) and now >= self._repeat_at[0] - 1e-9
        # The timer that calls this runs with the heartbeat's period: with a strict
        # comparison its jitter skipped every other beat (measured: 1.7 reports/s, not 4).
        due_beat = self._last_sent is None or now - self._last_sent >= 0.8 * self.status_period
        if due_repeat or due_beat or actions:
            self._repeat_at = [t for t in self._repeat_at if t > now + 1e-9]
            actions.append(self._send(now))
        return actions

    def leave(self, now: float) -> list[ParticipantAction]:
        return [PublishStatus(self.report(leaving=True))]

    # -- internals --------------------------------------------------------------------------

    def _heard_manager(self, manager_id: str, now: float | None) -> list[ParticipantAction]:
        if now is None:
            return []
        actions: list[ParticipantAction] = []
        last = self._last_message
        if last is not None and now - last > 1.6 * self.heartbeat_period:
            self._loss_seen = now
        self._manager_heard = self._last_message = now
        new_manager = bool(manager_id) and manager_id != self.manager_id
        if manager_id:
            self.manager_id = manager_id
        if self.manager_lost:
            self.manager_lost = False
            actions.append(ManagerFound(manager_id))
        if new_manager or actions:
            # A (re)started or regained manager learns about this node at once, not at the
            # next heartbeat: its recovery and our rejoining are faster.
            actions.append(self._send(now, repeat=True, always=True))
        return actions

    def _send(self, now: float, repeat: bool = False, always: bool = False) -> PublishStatus:
        """A report; with `repeat`, repeated shortly after if the link is lossy (`always`:
        whatever the link, for the rare reports a new manager must not miss)."""
        self._last_sent = now
        lossy = self._loss_seen is not None and now - self._loss_seen < LOSS_MEMORY
        if repeat and (always or lossy):
            self._repeat_at = [now + delay for delay in self.repeats]
        return PublishStatus(self.report())


# The longest heartbeat period a manager's message can ask for (a forged one must not
# silence a node for long): a minute, enough for 48,000 participants at the
# manager's default rate.
MAX_STATUS_PERIOD = 60.0


def _period(asked: float) -> float:
    """The manager's `status_period` as a participant takes it: a number within bounds."""
    if not isinstance(asked, (int, float)) or not asked > 0:  # also NaN
        return 0.0
    return min(float(asked), MAX_STATUS_PERIOD)


def _printable(text: str, limit: int = 1000) -> str:
    """Free text as the manager accepts it (printable, bounded): an exception's message
    often spans lines, and a report the manager refuses would be worse than a flat one."""
    return "".join(c if c.isprintable() else " " for c in text)[:limit]
