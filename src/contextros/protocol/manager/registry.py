"""Who is live: the participants, their declarations, their liveness and name clashes.

A participant is one (node, incarnation): a new incarnation under a known name is a
restart; an incarnation heard again after it was replaced means two live processes share
the name (both tracked, neither acknowledges for the other). A status is validated before
it changes anything; what is kept about a name is forgotten once it is neither live nor
among the `keep_dropped` dropped names (bounded memory whatever the network sends).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from contextros.protocol.events import (
    ManagerAction,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    ParticipantReport,
    ReportRejected,
)
from contextros.protocol.manager.base import ManagerBase
from contextros.protocol.manager.records import Key
from contextros.protocol.relations import (
    LayerDeclaration,
    merge_declarations,
    with_layer_files,
)
from contextros.protocol.state import MAX_EPOCH, LayerState
from contextros.protocol.validation import report_problems

# The highest epoch a manager adopts from a report: half the range, the rest for its own states.
ADOPTABLE_EPOCH = MAX_EPOCH // 2


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
    # The newest state it could not apply (0: none), and why.
    failed_epoch: int = 0
    error: str = ""


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


class Registry(ManagerBase):
    """The live participants and what they declare (see the module's docstring)."""

    @property
    def live_nodes(self) -> tuple[str, ...]:
        return tuple(sorted({node for node, _ in self._participants}))

    @property
    def dropped(self) -> tuple[str, ...]:
        return tuple(self._dropped)

    def declarations(self) -> dict[str, LayerDeclaration]:
        """The union of every live participant's declarations, with the relations of the
        manager's layer files, merged again only when a participant comes, goes or declares
        something else. Do not modify the result."""
        if self._declarations_cache is None:
            self._declarations_cache = with_layer_files(
                merge_declarations(
                    d for record in self._participants.values() for d in record.report.layers
                ),
                self.settings.layer_files,
            )
        return self._declarations_cache

    def conflicts(self) -> tuple[str, ...]:
        """Names under which more than one live process reports."""
        processes = Counter(node for node, _ in self._participants)
        return tuple(sorted(node for node, count in processes.items() if count > 1))

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
                failed_epoch=record.report.failed_epoch,
                error=record.report.error,
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

    # -- validation of statuses -------------------------------------------------------------

    def _report_problems(self, report: ParticipantReport) -> list[str]:
        # A participant repeats its declarations in every status: what it repeats from its
        # last accepted one is not checked again at every heartbeat.
        known = None
        if isinstance(report.node, str) and isinstance(report.incarnation, str):
            known = self._participants.get((report.node, report.incarnation))
        problems = report_problems(report, known.report if known is not None else None)
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

    # -- membership and liveness ------------------------------------------------------------

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
                self._declarations_cache = None
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

    def resumed_after(self, stall: float) -> None:
        """The manager did not run for `stall` seconds (its process waited for a core, or
        was stopped): that time is nobody's silence, as the reports sent meanwhile are still
        on their way in. Every participant's last report moves forward by it."""
        for record in self._participants.values():
            record.last_heard += stall
        self._oldest_heard += stall

    @property
    def status_period(self) -> float:
        """The heartbeat period the manager asks of its participants (the adapter sends it
        with every state and heartbeat): `settings.status_period` up to `status_rate`
        statuses per second, longer beyond (see `_adapt_status_period`)."""
        return self._status_period

    def liveness_bound(self, now: float) -> float:
        """The silence after which a participant is dropped: `liveness_timeout` at the
        settings' period, as many of the announced periods beyond it; after the period
        shortened, the longer bound holds until every participant had time to hear it."""
        settings = self.settings
        bound = settings.liveness_timeout * self._status_period / settings.status_period
        earlier, until = self._earlier_bound
        return max(bound, earlier) if now < until else bound

    def _adapt_status_period(self, now: float) -> None:
        """Keep the participants' statuses at `status_rate` per second at most: a longer
        period once they would exceed it, a shorter one (not below the settings' period)
        once they would stay under 40% of it. The period announced is 25% above the one
        needed, so a few more participants do not change it again."""
        settings = self.settings
        period = self._status_period
        count = len(self._participants)
        within = count <= settings.status_rate * period
        if within and (
            period <= settings.status_period or count > 0.4 * settings.status_rate * period
        ):
            return
        wanted = max(settings.status_period, 1.25 * count / settings.status_rate)
        if wanted < period:  # participants still on the longer period keep its bound
            self._earlier_bound = (self.liveness_bound(now), now + self.liveness_bound(now))
        self._status_period = wanted

    def _drop_silent(self, now: float) -> list[ManagerAction]:
        """Drop every participant silent for longer than the liveness bound (looked for
        only once the oldest report known may be that old)."""
        bound = self.liveness_bound(now)
        if now - self._oldest_heard <= bound:
            return []
        silent = []
        oldest = now
        for key, record in self._participants.items():
            heard = record.last_heard
            if now - heard > bound:
                silent.append((key, now - heard))
            elif heard < oldest:
                oldest = heard
        self._oldest_heard = oldest
        actions: list[ManagerAction] = []
        for key, silent_for in sorted(silent):
            record = self._participants[key]
            why = f"silent for {silent_for:.1f} s"
            if record.presumed:
                why = f"not heard for {silent_for:.1f} s since the manager restarted"
            actions += self._drop(key, why, now)
        return actions

    def _drop(self, key: Key, why: str, now: float) -> list[ManagerAction]:
        del self._participants[key]
        self._declarations_cache = None
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
