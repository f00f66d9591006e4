"""The Layer manager as a pure state machine: events in, actions out, time passed in.

Guarantees it keeps (and tests/protocol checks deterministically, also under random loss,
reordering, duplication and crashes):

- every state is a full snapshot with an epoch one above the previous one, and the epoch
  never goes down, not even across restarts (state file, participants' reports);
- nothing is published before the manager knows an epoch (its state file or a participant);
- a command naming a layer no live participant implements (after a grace period for a
  restarted manager), or breaking a declared relation, changes nothing and is answered
  with a message naming the culprits;
- a synchronous command succeeds only if every participant that was live when it was
  issued, every node it named and at least the count it asked for (one at least) applied
  its epoch (or a newer one); else it fails naming the nodes and why. Its answer carries
  its own epoch and that epoch's active layers;
- a participant silent for longer than `liveness_timeout` is dropped and reported; two
  live processes under one name are both tracked and neither acknowledges for the other;
- a status that fails validation (bad names, sizes, implausible epochs) changes nothing;
- memory stays bounded whatever the network sends: what is kept about a node name (its
  retired incarnations, the nodes it hosts) is forgotten once it is neither live nor among
  the `keep_dropped` names of dropped nodes, and at most `max_waiting_commands` commands wait.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    ParticipantReport,
    PublishHeartbeat,
    PublishProposal,
    PublishState,
    Reply,
    ReportRejected,
)
from contextros.protocol.relations import (
    DeclaredOrder,
    LayerDeclaration,
    declared_order,
    merge_declarations,
    order_note,
    relation_violations,
)
from contextros.protocol.state import INITIAL_STATE, MAX_EPOCH, LayerState
from contextros.protocol.validation import (
    command_problems,
    listing,
    report_problems,
)

RECOVERY_REQUESTER = "manager"
# The highest epoch a manager adopts from a report: half the range, the rest for its own states.
ADOPTABLE_EPOCH = MAX_EPOCH // 2

# A participant is one process under one incarnation; a node name may (wrongly) be used
# by two live processes at once, so the registry is keyed by both.
Key = tuple[str, str]


@dataclass(frozen=True)
class ManagerSettings:
    # A participant heartbeats every 0.25 s by default, so 3 s of silence means it is gone:
    # twelve lost heartbeats in a row (5e-7 at 30% loss). With 2 s, a 30%-loss link with
    # delay jitter still saw a spurious drop in about 40 activations (benchmarks/lossy_link).
    liveness_timeout: float = 3.0
    default_timeout: float = 5.0
    # An atomic vote holds every later command, so it lasts at most this long whatever the
    # command's timeout (a node that never votes must not stall the system for an hour).
    max_vote_time: float = 60.0
    # How long a (re)started manager listens to participants before deciding its first state;
    # prolonged while participants keep appearing (discovery is slower on a loaded machine),
    # by `recovery_quiet` after the last newcomer, up to three windows in all.
    recovery_window: float = 1.0
    recovery_quiet: float = 0.3
    manager_id: str = ""
    keep_dropped: int = 32
    # The manager's own heartbeat (best effort: the current state again), and the repeats
    # of a new state shortly after it was published, for a lossy link.
    heartbeat_period: float = 0.25
    repeats: tuple[float, ...] = (0.05, 0.15)
    # After recovery, a command naming a layer nobody implements yet waits this long for
    # participants still being discovered before it is refused.
    unknown_layer_grace: float = 2.0
    # Once the manager knows an epoch, a report more than this far above it is a lie (or a
    # stale state file): ignored and logged, never adopted nor persisted.
    max_epoch_jump: int = 10_000
    # At most one log line per sender this often about its rejected statuses.
    rejection_log_period: float = 10.0
    # A manager without a state file numbers its first state this far above the newest
    # epoch it heard: its predecessor may have published states that no participant
    # reported during recovery, and an epoch must never name two configurations.
    memoryless_epoch_gap: int = 1000
    # Commands waiting in the manager at once (synchronous ones for their acknowledgements,
    # others during recovery, an atomic vote or the unknown-layer grace): beyond it a new
    # command is refused at once, naming the limit. Anyone in the domain can send commands.
    max_waiting_commands: int = 1000


@dataclass
class ParticipantRecord:
    report: ParticipantReport
    last_heard: float


@dataclass(frozen=True)
class ParticipantView:
    node: str
    layers: tuple[str, ...]
    applied_epoch: int
    in_critical_section: bool
    silent_for: float
    lagging: bool
    hosted: tuple[str, ...] = ()
    incarnation: str = ""
    # Another live process reports under the same name.
    conflict: bool = False


@dataclass(frozen=True)
class RegistryView:
    """What `contextros status` shows: the state, the layers, who implements them, who lags."""

    state: LayerState
    layers: tuple[LayerDeclaration, ...]
    implemented_by: dict[str, tuple[str, ...]]
    participants: tuple[ParticipantView, ...]
    dropped: tuple[str, ...]
    recovering: bool
    conflicts: tuple[str, ...] = ()


@dataclass
class _PendingActivation:
    command: ActivationCommand
    state: LayerState
    started: float
    deadline: float
    waiting: set[Key]
    acknowledged: set[Key] = field(default_factory=set)
    lost: dict[Key, str] = field(default_factory=dict)
    failed: dict[Key, str] = field(default_factory=dict)
    changed: bool = True
    # How the declared `after` orders moved the requested layers ("" if they did not).
    note: str = ""


# The message of a command that leaves the configuration as it was (clients show it as is).
_NO_CHANGE = "no change"


@dataclass
class _Transaction:
    """An atomic activation in its voting phase: `proposal` is committed only if every
    target votes yes before `deadline`."""

    command: ActivationCommand
    proposal: LayerState
    started: float
    deadline: float
    targets: set[Key]
    timeout: float


class ManagerProtocol:
    """The manager's registry, state and pending synchronous activations."""

    def __init__(
        self,
        now: float,
        settings: ManagerSettings | None = None,
        saved_state: LayerState | None = None,
    ) -> None:
        self.settings = settings or ManagerSettings()
        self._state = saved_state or INITIAL_STATE
        self._participants: dict[Key, ParticipantRecord] = {}
        # Incarnations replaced by a newer one under the same name (a restart); hearing one
        # again means two live processes share the name.
        self._retired: dict[str, set[str]] = {}
        # The nodes each participant speaks for, kept past a drop to name them in answers.
        self._hosted: dict[str, tuple[str, ...]] = {}
        self._pending: list[_PendingActivation] = []
        self._queued: list[tuple[ActivationCommand, float]] = []
        self._order_cache: tuple[ActivationCommand, int, DeclaredOrder] | None = None
        self._declarations_cache: (
            tuple[tuple[ParticipantReport, ...], dict[str, LayerDeclaration]] | None
        ) = None
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
        # The open atomic activation, if any; commands wait behind it. Every proposed epoch
        # is used once: an aborted one is skipped, so a vote always names one proposal.
        self._transaction: _Transaction | None = None
        self._behind_transaction: list[tuple[ActivationCommand, float]] = []
        self._epoch_floor = 0
        self._memoryless = saved_state is None

    # -- queries ----------------------------------------------------------------------------

    @property
    def state(self) -> LayerState:
        return self._state

    @property
    def recovering(self) -> bool:
        return self._recovering_until is not None

    @property
    def live_nodes(self) -> tuple[str, ...]:
        return tuple(sorted({node for node, _ in self._participants}))

    @property
    def dropped(self) -> tuple[str, ...]:
        return tuple(self._dropped)

    @property
    def waiting_commands(self) -> int:
        """Commands received and not answered yet (bounded by `max_waiting_commands`)."""
        waiting = len(self._pending) + len(self._queued) + len(self._held)
        return waiting + len(self._behind_transaction) + (self._transaction is not None)

    def declarations(self) -> dict[str, LayerDeclaration]:
        """The union of every live participant's declarations (merged once per set of
        reports: a command asks for it several times). Do not modify the result."""
        reports = tuple(record.report for record in self._participants.values())
        cached = self._declarations_cache
        if (
            cached is not None
            and len(cached[0]) == len(reports)
            and all(a is b for a, b in zip(cached[0], reports, strict=True))
        ):
            return cached[1]
        merged = merge_declarations(d for report in reports for d in report.layers)
        self._declarations_cache = (reports, merged)
        return merged

    def conflicts(self) -> tuple[str, ...]:
        """Names under which more than one live process reports."""
        names = [node for node, _ in self._participants]
        return tuple(sorted({n for n in names if names.count(n) > 1}))

    def registry(self, now: float) -> RegistryView:
        implemented_by: dict[str, list[str]] = {}
        for (node, _), record in sorted(self._participants.items()):
            for declaration in record.report.layers:
                nodes = implemented_by.setdefault(declaration.name, [])
                if node not in nodes:
                    nodes.append(node)
        conflicts = self.conflicts()
        participants = tuple(
            ParticipantView(
                node=node,
                layers=tuple(d.name for d in record.report.layers),
                applied_epoch=record.report.applied_epoch,
                in_critical_section=record.report.in_critical_section,
                silent_for=max(0.0, now - record.last_heard),
                lagging=record.report.applied_epoch < self._state.epoch,
                hosted=record.report.hosted,
                incarnation=incarnation,
                conflict=node in conflicts,
            )
            for (node, incarnation), record in sorted(self._participants.items())
        )
        return RegistryView(
            state=self._state,
            layers=tuple(d for _, d in sorted(self.declarations().items())),
            implemented_by={name: tuple(nodes) for name, nodes in implemented_by.items()},
            participants=participants,
            dropped=tuple(self._dropped),
            recovering=self.recovering,
            conflicts=conflicts,
        )

    # -- events -----------------------------------------------------------------------------

    def receive_status(self, report: ParticipantReport, now: float) -> list[ManagerAction]:
        self._order_cache = None
        problems = self._report_problems(report)
        if problems:
            return self._rejected(report, problems, now)
        actions: list[ManagerAction] = []
        key = (report.node, report.incarnation)
        known = self._participants.get(key)
        if report.leaving:
            if known is not None:
                actions += self._drop(key, "left", now)
            return actions
        if known is not None and report.applied_epoch < known.report.applied_epoch:
            # A stale report (a node never goes back): it only proves the node is alive.
            known.last_heard = now
            return actions
        if known is None:
            actions += self._arrival(key, now)
        self._participants[key] = ParticipantRecord(report, last_heard=now)
        self._hosted[report.node] = report.hosted
        if report.node in self._dropped:  # it rejoined: the dropped list names absent nodes
            self._dropped.remove(report.node)
        if not self.recovering and self._is_ahead(report):
            actions += self._overtake(report, now)
        if known is None:
            actions += self._release_held(now)
        actions += self._settle_pending(now)
        actions += self._count_votes(now)
        return actions

    def receive_command(self, command: ActivationCommand, now: float) -> list[ManagerAction]:
        self._order_cache = None
        problems = command_problems(command)
        if problems:
            message = f"invalid command: {'; '.join(problems)}; nothing changed"
            return [Reply(command.request_id, self._result(False, message))]
        waiting = self.waiting_commands
        if waiting >= self.settings.max_waiting_commands:
            message = (
                f"refused: {waiting} commands are waiting in the manager already, at most "
                f"{self.settings.max_waiting_commands} (max_waiting_commands); nothing changed, "
                "try again later"
            )
            return [Reply(command.request_id, self._result(False, message))]
        if self.recovering:
            self._queued.append((command, now))
            return []
        return self._execute(command, now, now)

    def preview(self, command: ActivationCommand) -> tuple[str, tuple[str, ...]]:
        """What `command` would make active if it came now, changing nothing: ("", layers),
        or (the reason it would be refused, the current layers). While recovering, the
        current layers (the command will wait)."""
        self._order_cache = None
        if command_problems(command) or self.recovering:
            return ("invalid command" if command_problems(command) else ""), self._state.active
        problem, _ = self._validate(command)
        if problem:
            return problem, self._state.active
        return "", self._next_active(command)

    def would_hold(self, command: ActivationCommand, now: float) -> bool:
        """Whether `receive_command(command, now)` would keep `command` waiting rather than
        decide it (changing nothing): the manager recovers, an atomic vote is open, or the
        command names a layer nobody implements yet within the grace period. An adapter
        with work to do before a state is published (layers that drive ROS) keeps such a
        command itself until this is False, then previews it."""
        if command_problems(command):
            return False
        if self.recovering or self._transaction is not None:
            return True
        self._order_cache = None
        problem, unknown = self._validate(command)
        return bool(problem) and unknown and now < self._grace_until

    def tick(self, now: float) -> list[ManagerAction]:
        self._order_cache = None
        actions: list[ManagerAction] = []
        if self._recovering_until is not None and now >= self._recovering_until:
            actions += self._finish_recovery(now)
        if self._recovering_until is None:
            for key, record in sorted(self._participants.items()):
                silent = now - record.last_heard
                if silent > self.settings.liveness_timeout:
                    actions += self._drop(key, f"silent for {silent:.1f} s", now)
            actions += self._release_held(now)
            actions += self._settle_pending(now)
            actions += self._count_votes(now)
            if self._transaction is not None:  # repeated while the vote is open (lossy links)
                actions.append(PublishProposal(self._transaction.proposal))
        actions += self._heartbeat(now)
        return actions

    # -- validation of statuses -------------------------------------------------------------

    def _report_problems(self, report: ParticipantReport) -> list[str]:
        problems = report_problems(report)
        if problems:
            return problems
        # With no epoch known (no state file, nothing heard yet) only an absolute bound
        # applies, the participants being the manager's only memory; it leaves room above
        # for the memoryless gap and every later state (MAX_EPOCH is never reached).
        ceiling = ADOPTABLE_EPOCH
        if self._state.epoch:
            ceiling = min(ceiling, self._state.epoch + self.settings.max_epoch_jump)
        for name, epoch in (
            ("applied_epoch", report.applied_epoch),
            ("pending_epoch", report.pending_epoch),
            ("failed_epoch", report.failed_epoch),
        ):
            if epoch > ADOPTABLE_EPOCH:
                problems.append(f"{name} {epoch} is above {ADOPTABLE_EPOCH} (not adopted)")
            elif epoch > ceiling:
                problems.append(
                    f"{name} {epoch} is more than {self.settings.max_epoch_jump} above the "
                    f"manager's epoch {self._state.epoch} (not adopted; if it is genuine, "
                    "restart the manager without its state file)"
                )
        return problems

    def _rejected(
        self, report: ParticipantReport, problems: list[str], now: float
    ) -> list[ManagerAction]:
        sender = report.node if isinstance(report.node, str) else "?"
        sender = sender[:80]
        last = self._rejections_logged.get(sender)
        if last is not None and now - last < self.settings.rejection_log_period:
            return []
        if len(self._rejections_logged) > 1000:  # bounded, whatever the senders do
            self._rejections_logged.clear()
        self._rejections_logged[sender] = now
        return [ReportRejected(sender, tuple(problems[:5]))]

    # -- membership -------------------------------------------------------------------------

    def _arrival(self, key: Key, now: float) -> list[ManagerAction]:
        """A (node, incarnation) not in the registry reports: a join, a restart or a twin."""
        node, incarnation = key
        others = [k for k in self._participants if k[0] == node]
        retired = self._retired.setdefault(node, set())
        actions: list[ManagerAction] = []
        if incarnation in retired:
            # An incarnation we took for replaced is alive: two processes share the name.
            # Both are tracked from now on, and each must acknowledge for itself.
            retired.discard(incarnation)
            actions.append(ParticipantConflict(node))
            for pending in self._pending:
                if any(k[0] == node for k in pending.waiting | pending.acknowledged):
                    pending.waiting.add(key)
        else:
            actions.append(ParticipantJoined(node, restarted=bool(others)))
            for old in others:  # a restart: the new incarnation replaces the old ones
                del self._participants[old]
                retired.add(old[1])
                for pending in self._pending:
                    if old in pending.waiting:
                        pending.waiting.discard(old)
                        pending.waiting.add(key)
            if len(retired) > 16:  # bounded: only recent incarnations matter
                retired.clear()
            if self._recovering_until is not None:
                self._recovering_until = min(
                    max(self._recovering_until, now + self.settings.recovery_quiet),
                    self._recovery_limit,
                )
        return actions

    # -- recovery ---------------------------------------------------------------------------

    def _finish_recovery(self, now: float) -> list[ManagerAction]:
        self._recovering_until = None
        self._grace_until = now + self.settings.unknown_layer_grace
        newest = max(
            (r.report for r in self._participants.values()),
            key=lambda report: report.applied_epoch,
            default=None,
        )
        active = self._state.active
        epoch = self._state.epoch
        reason = "recovered from the state file" if epoch else "started with no previous state"
        if newest is not None and newest.applied_epoch > epoch:
            active, epoch = newest.active, newest.applied_epoch
            reason = f"recovered from {newest.node}"
        actions: list[ManagerAction] = []
        if self._memoryless and newest is not None:
            epoch = self._above_unknown(epoch)
        if epoch > 0 or newest is not None:
            # A fresh epoch even when nothing changed: the epoch is never reused, and lagging
            # participants converge on this snapshot. With no state file and nobody heard,
            # nothing is known yet: publish nothing until a participant reports.
            actions.append(self._publish(active, RECOVERY_REQUESTER, reason, now, epoch))
        for command, received in self._queued:
            actions += self._execute(command, now, received)
        self._queued.clear()
        return actions

    def _is_ahead(self, report: ParticipantReport) -> bool:
        """The node applied a state this manager did not publish, numbered like ours or higher
        (this manager restarted without memory of it)."""
        if report.applied_epoch > self._state.epoch:
            return True
        if self._state.epoch == 0:
            return True  # nothing published yet: the first report decides the first state
        foreign = report.applied_manager_id not in ("", self.settings.manager_id)
        return report.applied_epoch == self._state.epoch > 0 and foreign

    def _overtake(self, report: ParticipantReport, now: float) -> list[ManagerAction]:
        """A participant knows a newer epoch than ours: jump past it, never below."""
        actions: list[ManagerAction] = []
        if self._transaction is not None:
            why = f"{report.node} reported epoch {report.applied_epoch}, newer than the proposal"
            actions += self._abort(now, {report.node: why})
        if self._decided_here:
            active, reason = self._state.active, f"re-asserted over {report.node}'s epoch"
        elif report.applied_epoch == 0:
            active, reason = (), "started with no previous state"
        else:
            active, reason = report.active, f"recovered from {report.node}"
        above = report.applied_epoch
        if self._memoryless:
            # Whoever published that epoch may have published a few more nobody reported.
            above = self._above_unknown(above)
        return [*actions, self._publish(active, RECOVERY_REQUESTER, reason, now, above)]

    def _above_unknown(self, newest_heard: int) -> int:
        """The epoch a memoryless manager's first state goes above (see the setting); a
        system where nobody applied anything yet starts at 1."""
        if newest_heard == 0:
            return 0
        return newest_heard + self.settings.memoryless_epoch_gap - 1

    # -- commands ---------------------------------------------------------------------------

    def _execute(
        self, command: ActivationCommand, now: float, received: float
    ) -> list[ManagerAction]:
        if self._transaction is not None:
            # One decision at a time: what others ask waits for the vote's outcome.
            self._behind_transaction.append((command, received))
            return []
        problem, unknown = self._validate(command)
        if problem:
            if unknown and now < self._grace_until:
                # A (re)started manager may not have heard every participant yet.
                self._held.append((command, received))
                return []
            return [Reply(command.request_id, self._result(False, problem))]
        new_active = self._next_active(command)
        changes = new_active != self._state.active or self._state.epoch == 0
        if command.atomic and changes:
            return self._propose(command, new_active, now, received)
        note = self._order_note(command)
        actions: list[ManagerAction] = []
        if changes:
            self._decided_here = True
            actions.append(
                self._publish(new_active, command.requester, command.reason, now, self._state.epoch)
            )
        if not command.synchronous and not command.atomic:  # (atomic, no change: as sync)
            message = f"epoch {self._state.epoch} published{note}" if actions else _NO_CHANGE
            return [*actions, Reply(command.request_id, self._result(True, message))]
        timeout = command.timeout if command.timeout > 0 else self.settings.default_timeout
        self._pending.append(
            _PendingActivation(
                command=command,
                state=self._state,
                started=received,
                deadline=received + timeout,
                waiting=set(self._participants),
                changed=bool(actions),
                note=note,
            )
        )
        return actions + self._settle_pending(now)

    # -- atomic activation ------------------------------------------------------------------

    def _propose(
        self, command: ActivationCommand, active: tuple[str, ...], now: float, received: float
    ) -> list[ManagerAction]:
        timeout = command.timeout if command.timeout > 0 else self.settings.default_timeout
        timeout = min(timeout, self.settings.max_vote_time)
        speaks_for = {
            name
            for key, record in self._participants.items()
            for name in (key[0], *record.report.hosted)
        }
        absent = [n for n in command.expect_nodes if n not in speaks_for]
        problems = [f"expected node {listing(absent)} is not live"] if absent else []
        if not self._participants:
            problems.append("no live participant")
        elif len(speaks_for) < command.expect_count:
            problems.append(f"{len(speaks_for)} live node(s), {command.expect_count} expected")
        if problems:
            message = f"atomic activation not started, nothing changed: {'; '.join(problems)}"
            result = ActivationResult(
                False,
                message,
                self._state.epoch,
                self._state.active,
                not_acknowledged=tuple(sorted(absent)),
            )
            return [Reply(command.request_id, result)]
        epoch = max(self._state.epoch, self._epoch_floor) + 1
        self._epoch_floor = epoch
        proposal = LayerState(
            epoch=epoch,
            active=active,
            requester=command.requester,
            reason=command.reason,
            stamp=now,
            manager_id=self.settings.manager_id,
        )
        self._transaction = _Transaction(
            command=command,
            proposal=proposal,
            started=received,
            deadline=now + timeout,
            targets=set(self._participants),
            timeout=timeout,
        )
        return [PublishProposal(proposal), *self._count_votes(now)]

    def _count_votes(self, now: float) -> list[ManagerAction]:
        """Commit once every target voted yes; abort on a veto, a lost target or the timeout."""
        transaction = self._transaction
        if transaction is None:
            return []
        epoch = transaction.proposal.epoch
        vetoes: dict[str, str] = {}
        missing: list[Key] = []
        for key in sorted(transaction.targets):
            record = self._participants.get(key)
            if record is None:
                vetoes[key[0]] = "lost before voting"
            elif record.report.vote_epoch != epoch or (
                record.report.vote_manager_id != self.settings.manager_id
            ):
                missing.append(key)  # no vote yet, or one on another manager's proposal
            elif not record.report.vote_yes:
                vetoes[key[0]] = f"vetoed: {record.report.vote_reason or 'no reason given'}"
        if vetoes:
            return self._abort(now, vetoes)
        if missing and now >= transaction.deadline:
            limit = f"{transaction.timeout:g} s"
            return self._abort(now, {key[0]: f"did not vote within {limit}" for key in missing})
        if missing:
            return []
        return self._commit(now)

    def _commit(self, now: float) -> list[ManagerAction]:
        transaction = self._transaction
        assert transaction is not None
        self._transaction = None
        self._decided_here = True
        proposal = transaction.proposal
        self._epoch_floor = proposal.epoch - 1  # the proposed epoch itself is committed
        published = self._publish(
            proposal.active, proposal.requester, proposal.reason, now, proposal.epoch - 1
        )
        # The second phase waits for the acknowledgements as a synchronous activation does,
        # with the same timeout again.
        self._pending.append(
            _PendingActivation(
                command=transaction.command,
                state=self._state,
                started=transaction.started,
                deadline=now + transaction.timeout,
                waiting={key for key in transaction.targets if key in self._participants},
            )
        )
        return [published, *self._settle_pending(now), *self._run_behind_transaction(now)]

    def _abort(self, now: float, reasons: dict[str, str]) -> list[ManagerAction]:
        transaction = self._transaction
        assert transaction is not None
        self._transaction = None
        for node, why in list(reasons.items()):
            for hosted in self._hosted.get(node, ()):
                reasons.setdefault(hosted, f"hosted by {node}, {why}")
        shown = sorted(reasons.items())
        listing_ = "; ".join(f"{node} {why}" for node, why in shown[:20])
        if len(shown) > 20:
            listing_ += f"; and {len(shown) - 20} more"
        epoch = transaction.proposal.epoch
        result = ActivationResult(
            success=False,
            message=f"atomic activation of epoch {epoch} aborted, nothing changed: {listing_}",
            epoch=self._state.epoch,
            active=self._state.active,
            not_acknowledged=tuple(node for node, _ in shown),
            elapsed=now - transaction.started,
        )
        return [Reply(transaction.command.request_id, result), *self._run_behind_transaction(now)]

    def _run_behind_transaction(self, now: float) -> list[ManagerAction]:
        actions: list[ManagerAction] = []
        while self._behind_transaction and self._transaction is None:
            command, received = self._behind_transaction.pop(0)
            actions += self._execute(command, now, received)
        return actions

    def _release_held(self, now: float) -> list[ManagerAction]:
        """Retry commands held for unknown layers: now known, or the grace period is over."""
        if not self._held:
            return []
        held, self._held = self._held, []
        actions: list[ManagerAction] = []
        for command, received in held:
            _, unknown = self._validate(command)
            if unknown and now < self._grace_until:
                self._held.append((command, received))
            else:
                actions += self._execute(command, now, received)
        return actions

    def _validate(self, command: ActivationCommand) -> tuple[str, bool]:
        """The reason to refuse `command` ("" if none), and whether it is unknown layers."""
        both = sorted(set(command.activate) & set(command.deactivate))
        if both:
            return f"both activated and deactivated: {listing(both)}; nothing changed", False
        declarations = self.declarations()
        unknown = [name for name in command.activate if name not in declarations]
        unknown += [
            name
            for name in command.deactivate
            if name not in declarations and name not in self._state.active
        ]
        if unknown:
            known = listing(sorted(declarations), limit=20) or "none"
            names = listing(dict.fromkeys(unknown), quote=True)
            message = (
                f"unknown layer {names}: no live participant implements it "
                f"(known layers: {known}); nothing changed"
            )
            return message, True
        rivals = _group_rivals(command.activate, declarations)
        if rivals:
            return f"relation violated: {rivals}; activate only one of them; nothing changed", False
        order = self._declared_order(command)
        if order.cycle:
            return (
                f"relation violated: the declared 'after' orders of {listing(order.cycle)} "
                "form a cycle; nothing changed",
                False,
            )
        before = set(relation_violations(self._state.active, declarations))
        introduced = [
            problem
            for problem in relation_violations(self._next_active(command), declarations)
            if problem not in before
        ]
        if introduced:
            causes = self._displaced(command, declarations, introduced)
            return (
                f"relation violated: {'; '.join(introduced[:5])}{causes}; nothing changed",
                False,
            )
        return "", False

    def _displaced(
        self,
        command: ActivationCommand,
        declarations: dict[str, LayerDeclaration],
        problems: list[str],
    ) -> str:
        """Which requested layer would push an active one out of its exclusive group, when
        a broken `requires` names that one: the hidden cause (activating Flight drops
        Wheels, which LowBattery requires)."""
        needed = {
            p.split(" requires ", 1)[1].split(",", 1)[0] for p in problems if " requires " in p
        }
        causes = []
        for name in dict.fromkeys(command.activate):
            groups = _groups_of(name, declarations)
            for other in self._state.active:
                shared = groups & _groups_of(other, declarations)
                if other != name and other in needed and shared and other not in command.deactivate:
                    group = sorted(shared)[0]
                    causes.append(
                        f"activating {name} would deactivate {other} "
                        f"(both in exclusive group {group!r})"
                    )
        return f" ({'; '.join(causes[:5])})" if causes else ""

    def _next_active(self, command: ActivationCommand) -> tuple[str, ...]:
        """The next configuration, composed in the order the `after` relations declare."""
        return self._declared_order(command).layers

    def _order_note(self, command: ActivationCommand) -> str:
        """'; composed as declared: Rubble after Flooded' when the requested order moved."""
        return order_note(self._declared_order(command).moved)

    def _declared_order(self, command: ActivationCommand) -> DeclaredOrder:
        # Asked several times while one command is validated and executed: computed once per
        # command and state (the cache is dropped by every event, see `_fresh`).
        cached = self._order_cache
        if cached is not None and cached[0] is command and cached[1] == self._state.epoch:
            return cached[2]
        order = declared_order(self._unordered_next(command), self.declarations())
        self._order_cache = (command, self._state.epoch, order)
        return order

    def _unordered_next(self, command: ActivationCommand) -> tuple[str, ...]:
        # As the core's `switch`: deactivate, then activate; an active layer keeps its place,
        # a new one becomes outermost, and activating a group member drops the others.
        declarations = self.declarations()
        off = set(command.deactivate)
        layers = [name for name in self._state.active if name not in off]
        for name in dict.fromkeys(command.activate):
            groups = _groups_of(name, declarations)
            if groups:
                layers = [
                    other
                    for other in layers
                    if other == name or not (_groups_of(other, declarations) & groups)
                ]
            if name not in layers:
                layers.append(name)
        return tuple(layers)

    def _publish(
        self, active: tuple[str, ...], requester: str, reason: str, now: float, above: int
    ) -> PublishState:
        self._state = LayerState(
            epoch=max(above, self._state.epoch, self._epoch_floor) + 1,
            active=tuple(active),
            requester=requester,
            reason=reason,
            stamp=now,
            manager_id=self.settings.manager_id,
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
        else:
            beat = self._state
        return [PublishHeartbeat(beat)]

    def _someone_lags(self) -> bool:
        return any(r.report.applied_epoch < self._state.epoch for r in self._participants.values())

    # -- acknowledgements -------------------------------------------------------------------

    def _drop(self, key: Key, why: str, now: float) -> list[ManagerAction]:
        del self._participants[key]
        node = key[0]
        still_there = any(k[0] == node for k in self._participants)
        if not still_there:
            if node in self._dropped:
                self._dropped.remove(node)
            if self._dropped.maxlen and len(self._dropped) >= self._dropped.maxlen:
                self._forget(self._dropped[0])  # pushed out of the kept dropped names next
            self._dropped.append(node)
            if node not in self._dropped:  # keep_dropped == 0
                self._forget(node)
        for pending in self._pending:
            if key in pending.waiting:
                pending.waiting.discard(key)
                pending.lost[key] = f"dropped, {why}"
        label = node if not still_there else f"{node} (incarnation {key[1]})"
        actions: list[ManagerAction] = [ParticipantDropped(label, why)]
        if self._transaction is not None and key in self._transaction.targets:
            actions += self._abort(now, {node: f"lost before the commit ({why})"})
        return [*actions, *self._settle_pending(now)]

    def _forget(self, node: str) -> None:
        """What is kept about `node` past its drop, unless it is live again (bounded memory:
        only live participants and the kept dropped names have entries)."""
        if any(k[0] == node for k in self._participants):
            return
        self._hosted.pop(node, None)
        self._retired.pop(node, None)

    def _settle_pending(self, now: float) -> list[ManagerAction]:
        replies: list[ManagerAction] = []
        still_pending: list[_PendingActivation] = []
        for pending in self._pending:
            epoch = pending.state.epoch
            self._add_expected(pending)
            for key in sorted(pending.waiting):
                report = self._participants[key].report
                if report.applied_epoch >= epoch:
                    pending.waiting.discard(key)
                    pending.acknowledged.add(key)
                elif report.failed_epoch >= epoch:
                    pending.waiting.discard(key)
                    pending.failed[key] = f"failed to apply: {report.error or 'no reason given'}"
            missing = self._missing(pending)
            # Expected nodes may still join; without expectations, nobody left to wait for
            # decides the answer (and reaching no node at all is a failure).
            expecting = pending.command.expect_nodes or pending.command.expect_count
            settled = not missing or pending.lost or pending.failed or not expecting
            if not pending.waiting and settled:
                replies.append(self._finish(pending, now, timed_out=False))
            elif now >= pending.deadline:
                replies.append(self._finish(pending, now, timed_out=True))
            else:
                still_pending.append(pending)
        self._pending = still_pending
        return replies

    def _add_expected(self, pending: _PendingActivation) -> None:
        """An expected node that joined after the command must acknowledge it too."""
        wanted = set(pending.command.expect_nodes)
        if not wanted:
            return
        counted = pending.waiting | pending.acknowledged | set(pending.lost) | set(pending.failed)
        for key, record in self._participants.items():
            speaks_for = {key[0], *record.report.hosted}
            if key not in counted and speaks_for & wanted:
                pending.waiting.add(key)

    def _acknowledged_names(self, pending: _PendingActivation) -> set[str]:
        """Nodes every process of whose name applied the epoch, with the nodes they host."""
        refused = {key[0] for key in (*pending.waiting, *pending.lost, *pending.failed)}
        names: set[str] = set()
        for node, _ in pending.acknowledged:
            if node not in refused:
                names.add(node)
                names.update(self._hosted.get(node, ()))
        return names

    def _missing(self, pending: _PendingActivation) -> list[str]:
        """What the requester asked for that is not (yet) acknowledged, as sentences."""
        acknowledged = self._acknowledged_names(pending)
        absent = [n for n in pending.command.expect_nodes if n not in acknowledged]
        problems = [f"expected node {listing(absent)} did not apply it"] if absent else []
        wanted = max(pending.command.expect_count, 1)
        if len(acknowledged) < wanted:
            problems.append(
                f"applied by {len(acknowledged)} node(s), {wanted} expected"
                if pending.command.expect_count
                else "it reached no node"
            )
        return problems

    def _finish(self, pending: _PendingActivation, now: float, timed_out: bool) -> Reply:
        conflicts = set(self.conflicts())
        reasons: dict[str, str] = {}
        for key, why in [*pending.lost.items(), *pending.failed.items()]:
            reasons[key[0]] = why
        if timed_out:
            for key in pending.waiting:
                reasons[key[0]] = self._why_not_applied(key, pending.state.epoch)
        for node in list(reasons):
            if node in conflicts:
                reasons[node] += "; two live processes are named so"
        # A participant speaks for the other nodes of its process: name them too.
        for node, why in list(reasons.items()):
            for hosted in self._hosted.get(node, ()):
                reasons[hosted] = f"hosted by {node}, {why}"
        acknowledged = self._acknowledged_names(pending) - set(reasons)
        missing = self._missing(pending)
        epoch = pending.state.epoch
        if reasons or missing:
            parts = []
            if reasons:
                limit = f" within {pending.deadline - pending.started:g} s" if timed_out else ""
                shown = sorted(reasons.items())
                listing_ = "; ".join(f"{node} ({why})" for node, why in shown[:20])
                if len(shown) > 20:
                    listing_ += f"; and {len(shown) - 20} more"
                parts.append(f"not acknowledged{limit} by {listing_}")
            parts += missing
            message = f"epoch {epoch} failed: {'; '.join(parts)}"
            if not reasons:
                message = f"epoch {epoch} not confirmed: {'; '.join(parts)}"
        elif not pending.changed:
            message = f"{_NO_CHANGE}: epoch {epoch} already has that configuration"
        else:
            message = f"epoch {epoch} applied by {len(acknowledged)} node(s){pending.note}"
        result = ActivationResult(
            success=not reasons and not missing,
            message=message,
            epoch=epoch,
            active=pending.state.active,
            acknowledged=tuple(sorted(acknowledged)),
            not_acknowledged=tuple(sorted(set(reasons) | set(self._absent(pending)))),
            elapsed=now - pending.started,
        )
        return Reply(pending.command.request_id, result)

    def _absent(self, pending: _PendingActivation) -> list[str]:
        acknowledged = self._acknowledged_names(pending)
        return [n for n in pending.command.expect_nodes if n not in acknowledged]

    def _why_not_applied(self, key: Key, epoch: int) -> str:
        report = self._participants[key].report
        if report.pending_epoch >= epoch or report.in_critical_section:
            return f"in a critical section, still on epoch {report.applied_epoch}"
        return f"still on epoch {report.applied_epoch}"

    def _result(self, success: bool, message: str) -> ActivationResult:
        return ActivationResult(success, message, self._state.epoch, self._state.active)


def _groups_of(name: str, declarations: dict[str, LayerDeclaration]) -> frozenset[str]:
    declaration = declarations.get(name)
    return declaration.groups if declaration else frozenset()


def _group_rivals(activate: tuple[str, ...], declarations: dict[str, LayerDeclaration]) -> str:
    """Two layers of one exclusive group asked for in the same command."""
    seen: dict[str, str] = {}
    for name in dict.fromkeys(activate):
        for group in sorted(_groups_of(name, declarations)):
            other = seen.setdefault(group, name)
            if other != name:
                return f"{other} and {name} are both in exclusive group {group!r}"
    return ""
