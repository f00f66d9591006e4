"""The Layer manager as a pure state machine: events in, actions out, time passed in.

Guarantees it keeps (and tests/protocol checks deterministically):

- every state is a full snapshot with an epoch one above the previous one, and the epoch
  never goes down, not even across restarts (state file, participants' reports);
- a command naming a layer no live participant implements, or breaking a declared relation,
  changes nothing and is answered with a message naming the culprits;
- a synchronous command is answered once every participant that was live when it was issued
  has applied its epoch (or a newer one), or has been dropped, failed, or timed out, with
  those nodes named;
- a participant silent for longer than `liveness_timeout` is dropped and reported.
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
    PublishState,
    Reply,
)
from contextros.protocol.relations import (
    LayerDeclaration,
    merge_declarations,
    relation_violations,
)
from contextros.protocol.state import INITIAL_STATE, LayerState

RECOVERY_REQUESTER = "manager"


@dataclass(frozen=True)
class ManagerSettings:
    # A participant heartbeats every 0.25 s by default, so 2 s of silence means it is gone.
    liveness_timeout: float = 2.0
    default_timeout: float = 5.0
    # How long a (re)started manager listens to participants before deciding its first state;
    # prolonged while participants keep appearing (discovery is slower on a loaded machine),
    # by `recovery_quiet` after the last newcomer, up to three windows in all.
    recovery_window: float = 1.0
    recovery_quiet: float = 0.3
    manager_id: str = ""
    keep_dropped: int = 32


@dataclass
class ParticipantRecord:
    report: ParticipantReport
    last_heard: float
    # Earlier incarnations under this name: a process never reuses one, so hearing one
    # again means two live nodes share the name.
    retired: frozenset[str] = frozenset()
    conflict_reported: bool = False


@dataclass(frozen=True)
class ParticipantView:
    node: str
    layers: tuple[str, ...]
    applied_epoch: int
    in_critical_section: bool
    silent_for: float
    lagging: bool
    hosted: tuple[str, ...] = ()


@dataclass(frozen=True)
class RegistryView:
    """What `contextros status` shows: the state, the layers, who implements them, who lags."""

    state: LayerState
    layers: tuple[LayerDeclaration, ...]
    implemented_by: dict[str, tuple[str, ...]]
    participants: tuple[ParticipantView, ...]
    dropped: tuple[str, ...]
    recovering: bool


@dataclass
class _PendingActivation:
    command: ActivationCommand
    epoch: int
    started: float
    deadline: float
    waiting: set[str]
    acknowledged: set[str] = field(default_factory=set)
    lost: dict[str, str] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)


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
        self._participants: dict[str, ParticipantRecord] = {}
        # The nodes each participant speaks for, kept past a drop to name them in answers.
        self._hosted: dict[str, tuple[str, ...]] = {}
        self._pending: list[_PendingActivation] = []
        self._queued: list[tuple[ActivationCommand, float]] = []
        self._dropped: deque[str] = deque(maxlen=self.settings.keep_dropped)
        self._recovering_until: float | None = now + self.settings.recovery_window
        self._recovery_limit = now + 3 * self.settings.recovery_window
        # Until a client decides something, the newest configuration a participant reports
        # is the truth (the manager restarted without a state file, or with an older one).
        self._decided_here = False

    # -- queries ----------------------------------------------------------------------------

    @property
    def state(self) -> LayerState:
        return self._state

    @property
    def recovering(self) -> bool:
        return self._recovering_until is not None

    @property
    def live_nodes(self) -> tuple[str, ...]:
        return tuple(sorted(self._participants))

    def declarations(self) -> dict[str, LayerDeclaration]:
        return merge_declarations(
            d for record in self._participants.values() for d in record.report.layers
        )

    def registry(self, now: float) -> RegistryView:
        implemented_by: dict[str, list[str]] = {}
        for node, record in sorted(self._participants.items()):
            for declaration in record.report.layers:
                implemented_by.setdefault(declaration.name, []).append(node)
        participants = tuple(
            ParticipantView(
                node=node,
                layers=tuple(d.name for d in record.report.layers),
                applied_epoch=record.report.applied_epoch,
                in_critical_section=record.report.in_critical_section,
                silent_for=max(0.0, now - record.last_heard),
                lagging=record.report.applied_epoch < self._state.epoch,
                hosted=record.report.hosted,
            )
            for node, record in sorted(self._participants.items())
        )
        return RegistryView(
            state=self._state,
            layers=tuple(d for _, d in sorted(self.declarations().items())),
            implemented_by={name: tuple(nodes) for name, nodes in implemented_by.items()},
            participants=participants,
            dropped=tuple(self._dropped),
            recovering=self.recovering,
        )

    # -- events -----------------------------------------------------------------------------

    def receive_status(self, report: ParticipantReport, now: float) -> list[ManagerAction]:
        actions: list[ManagerAction] = []
        known = self._participants.get(report.node)
        if report.leaving:
            if known is not None and known.report.incarnation == report.incarnation:
                actions += self._drop(report.node, "left", now)
            return actions
        if (
            known is not None
            and known.report.incarnation == report.incarnation
            and report.applied_epoch < known.report.applied_epoch
        ):
            # A stale report (a node never goes back): it only proves the node is alive.
            known.last_heard = now
            return actions
        record = ParticipantRecord(report, last_heard=now)
        if known is not None:
            record.retired = known.retired
            record.conflict_reported = known.conflict_reported
        if known is not None and report.incarnation in known.retired:
            record.retired = known.retired | {known.report.incarnation}
            if not known.conflict_reported:
                record.conflict_reported = True
                actions.append(ParticipantConflict(report.node))
        elif known is None or known.report.incarnation != report.incarnation:
            actions.append(ParticipantJoined(report.node, restarted=known is not None))
            if known is not None:
                record.retired = known.retired | {known.report.incarnation}
            if self._recovering_until is not None:
                self._recovering_until = min(
                    max(self._recovering_until, now + self.settings.recovery_quiet),
                    self._recovery_limit,
                )
        self._participants[report.node] = record
        self._hosted[report.node] = report.hosted
        if not self.recovering and self._is_ahead(report):
            actions += self._overtake(report, now)
        actions += self._settle_pending(now)
        return actions

    def receive_command(self, command: ActivationCommand, now: float) -> list[ManagerAction]:
        if self.recovering:
            self._queued.append((command, now))
            return []
        return self._execute(command, now)

    def tick(self, now: float) -> list[ManagerAction]:
        actions: list[ManagerAction] = []
        if self._recovering_until is not None:
            if now < self._recovering_until:
                return actions
            actions += self._finish_recovery(now)
        for node, record in sorted(self._participants.items()):
            silent = now - record.last_heard
            if silent > self.settings.liveness_timeout:
                actions += self._drop(node, f"silent for {silent:.1f} s", now)
        actions += self._settle_pending(now)
        return actions

    # -- recovery ---------------------------------------------------------------------------

    def _finish_recovery(self, now: float) -> list[ManagerAction]:
        self._recovering_until = None
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
        # A fresh epoch even when nothing changed: the epoch is never reused, and lagging
        # participants converge on this snapshot.
        actions: list[ManagerAction] = [
            self._publish(active, RECOVERY_REQUESTER, reason, now, epoch)
        ]
        for command, received in self._queued:
            actions += self._execute(command, received)
        self._queued.clear()
        return actions

    def _is_ahead(self, report: ParticipantReport) -> bool:
        """The node applied a state this manager did not publish, numbered like ours or higher
        (this manager restarted without memory of it)."""
        if report.applied_epoch > self._state.epoch:
            return True
        foreign = report.applied_manager_id not in ("", self.settings.manager_id)
        return report.applied_epoch == self._state.epoch > 0 and foreign

    def _overtake(self, report: ParticipantReport, now: float) -> list[ManagerAction]:
        """A participant knows a newer epoch than ours: jump past it, never below."""
        if self._decided_here:
            active, reason = self._state.active, f"re-asserted over {report.node}'s epoch"
        else:
            active, reason = report.active, f"recovered from {report.node}"
        return [self._publish(active, RECOVERY_REQUESTER, reason, now, report.applied_epoch)]

    # -- commands ---------------------------------------------------------------------------

    def _execute(self, command: ActivationCommand, now: float) -> list[ManagerAction]:
        problem = self._validate(command)
        if problem:
            return [Reply(command.request_id, self._result(False, problem))]
        new_active = self._next_active(command)
        actions: list[ManagerAction] = []
        if new_active != self._state.active:
            self._decided_here = True
            actions.append(
                self._publish(new_active, command.requester, command.reason, now, self._state.epoch)
            )
        if not command.synchronous:
            message = f"epoch {self._state.epoch} published" if actions else "no change"
            return [*actions, Reply(command.request_id, self._result(True, message))]
        timeout = command.timeout if command.timeout > 0 else self.settings.default_timeout
        self._pending.append(
            _PendingActivation(
                command=command,
                epoch=self._state.epoch,
                started=now,
                deadline=now + timeout,
                waiting=set(self._participants),
            )
        )
        return actions + self._settle_pending(now)

    def _validate(self, command: ActivationCommand) -> str:
        both = sorted(set(command.activate) & set(command.deactivate))
        if both:
            return f"both activated and deactivated: {', '.join(both)}; nothing changed"
        declarations = self.declarations()
        unknown = [name for name in command.activate if name not in declarations]
        unknown += [
            name
            for name in command.deactivate
            if name not in declarations and name not in self._state.active
        ]
        if unknown:
            known = ", ".join(sorted(declarations)) or "none"
            names = ", ".join(repr(name) for name in dict.fromkeys(unknown))
            return (
                f"unknown layer {names}: no live participant implements it "
                f"(known layers: {known}); nothing changed"
            )
        rivals = _group_rivals(command.activate, declarations)
        if rivals:
            return f"relation violated: {rivals}; activate only one of them; nothing changed"
        before = set(relation_violations(self._state.active, declarations))
        introduced = [
            problem
            for problem in relation_violations(self._next_active(command), declarations)
            if problem not in before
        ]
        if introduced:
            return f"relation violated: {'; '.join(introduced)}; nothing changed"
        return ""

    def _next_active(self, command: ActivationCommand) -> tuple[str, ...]:
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
            epoch=max(above, self._state.epoch) + 1,
            active=tuple(active),
            requester=requester,
            reason=reason,
            stamp=now,
            manager_id=self.settings.manager_id,
        )
        return PublishState(self._state)

    # -- acknowledgements -------------------------------------------------------------------

    def _drop(self, node: str, why: str, now: float) -> list[ManagerAction]:
        del self._participants[node]
        self._dropped.append(node)
        for pending in self._pending:
            if node in pending.waiting:
                pending.waiting.discard(node)
                pending.lost[node] = f"dropped, {why}"
        return [ParticipantDropped(node, why), *self._settle_pending(now)]

    def _settle_pending(self, now: float) -> list[ManagerAction]:
        replies: list[ManagerAction] = []
        still_pending: list[_PendingActivation] = []
        for pending in self._pending:
            for node in sorted(pending.waiting):
                report = self._participants[node].report
                if report.applied_epoch >= pending.epoch:
                    pending.waiting.discard(node)
                    pending.acknowledged.add(node)
                elif report.failed_epoch >= pending.epoch:
                    pending.waiting.discard(node)
                    pending.failed[node] = f"failed to apply: {report.error or 'no reason given'}"
            if not pending.waiting:
                replies.append(self._finish(pending, now, timed_out=False))
            elif now >= pending.deadline:
                replies.append(self._finish(pending, now, timed_out=True))
            else:
                still_pending.append(pending)
        self._pending = still_pending
        return replies

    def _finish(self, pending: _PendingActivation, now: float, timed_out: bool) -> Reply:
        reasons = dict(pending.lost)
        reasons.update(pending.failed)
        if timed_out:
            for node in pending.waiting:
                reasons[node] = self._why_not_applied(node, pending.epoch)
        # A participant speaks for the other nodes of its process: name them too.
        for node, why in list(reasons.items()):
            for hosted in self._hosted.get(node, ()):
                reasons[hosted] = f"hosted by {node}, {why}"
        acknowledged = {
            name for node in pending.acknowledged for name in (node, *self._hosted.get(node, ()))
        }
        elapsed = now - pending.started
        if reasons:
            listing = "; ".join(f"{node} ({why})" for node, why in sorted(reasons.items()))
            limit = f" within {pending.deadline - pending.started:g} s" if timed_out else ""
            message = f"epoch {pending.epoch} not acknowledged{limit} by {listing}"
        else:
            message = f"epoch {pending.epoch} applied by {len(acknowledged)} node(s)"
        result = ActivationResult(
            success=not reasons,
            message=message,
            epoch=pending.epoch,
            active=self._state.active,
            acknowledged=tuple(sorted(acknowledged)),
            not_acknowledged=tuple(sorted(reasons)),
            elapsed=elapsed,
        )
        return Reply(pending.command.request_id, result)

    def _why_not_applied(self, node: str, epoch: int) -> str:
        report = self._participants[node].report
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
