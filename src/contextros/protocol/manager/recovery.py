"""A (re)started manager's first state, and catching up with a participant ahead of it.

The manager listens for `recovery_window` (longer while participants keep appearing, three
windows at most) and then publishes a fresh epoch above everything it knows: its state file
and the participants' reports. Without a state file it numbers that state
`memoryless_epoch_gap` above what it heard (its predecessor may have published more), and
nothing is published before the manager knows an epoch.
"""

from __future__ import annotations

from contextros.protocol.events import ManagerAction, ParticipantReport
from contextros.protocol.manager.base import ManagerBase

RECOVERY_REQUESTER = "manager"


class Recovery(ManagerBase):
    """Deciding the first state, and overtaking a participant that knows a newer epoch."""

    def _finish_recovery(self, now: float) -> list[ManagerAction]:
        self._recovering_until = None
        self._grace_until = now + self.settings.unknown_layer_grace
        for record in self._participants.values():
            if record.presumed:  # a full liveness bound from now on to report
                record.last_heard = now
        newest = max(
            (r.report for r in self._participants.values() if not r.presumed),
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

    def prolong_recovery(self, until: float) -> None:
        """Recover until `until` at least (within the limit of three windows): the adapter
        sees another manager it has not heard yet, and must not publish before it does."""
        if self._recovering_until is not None:
            self._recovering_until = min(max(self._recovering_until, until), self._recovery_limit)

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
