"""The atomic activation: every target votes on a proposal before anything changes.

Any veto (once every target voted, so the answer names each node that said no), a lost
target or the timeout (at most `max_vote_time`) aborts with nothing changed anywhere;
otherwise the proposed epoch is committed and then acknowledged as a synchronous
activation. Other commands wait behind an open vote. A proposed epoch is
used once: an aborted one is skipped, so a vote always names one proposal.
"""

from __future__ import annotations

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    PublishProposal,
    Reply,
)
from contextros.protocol.manager.base import ManagerBase
from contextros.protocol.manager.records import Key, PendingActivation, Transaction
from contextros.protocol.state import LayerState
from contextros.protocol.validation import listing


class AtomicVotes(ManagerBase):
    """The open atomic activation (`_transaction`) and the commands behind it."""

    def _propose(
        self,
        command: ActivationCommand,
        active: tuple[str, ...],
        now: float,
        received: float,
        explicit: tuple[str, ...] | None = None,
    ) -> list[ManagerAction]:
        # The whole command, vote and acknowledgements, ends at its deadline.
        deadline = min(self._deadline(command, received), received + self.settings.max_vote_time)
        timeout = deadline - received
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
            status_period=self._status_period,
        )
        self._transaction = Transaction(
            command=command,
            proposal=proposal,
            started=received,
            deadline=deadline,
            targets=set(self._participants),
            timeout=timeout,
            explicit=explicit,
        )
        return [PublishProposal(proposal), *self._count_votes(now)]

    def _count_votes(self, now: float, voter: Key | None = None) -> list[ManagerAction]:
        """Commit once every target voted yes; abort on a veto, a lost target or the timeout.

        `voter`: only this known participant's status changed since the last count, so
        the count is kept up to date with it alone until it decides something."""
        transaction = self._transaction
        if transaction is None:
            return []
        epoch = transaction.proposal.epoch
        if voter is not None and transaction.counted:
            if voter in transaction.targets:
                report = self._participants[voter].report
                voted = report.vote_epoch == epoch
                if voted and report.vote_manager_id == self.settings.manager_id:
                    transaction.voted.add(voter)
                else:
                    transaction.voted.discard(voter)
            undecided = len(transaction.voted) < len(transaction.targets)
            if undecided and now < transaction.deadline:
                return []
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
        transaction.counted = True
        transaction.voted = transaction.targets.difference(missing)
        if missing and now < transaction.deadline:
            return []  # even after a no: the answer names every node that says no
        limit = f"{transaction.timeout:g} s"
        vetoes.update({key[0]: f"did not vote within {limit}" for key in missing})
        if vetoes:
            return self._abort(now, vetoes)
        return self._commit(now)

    def _commit(self, now: float) -> list[ManagerAction]:
        transaction = self._transaction
        assert transaction is not None
        self._transaction = None
        self._decided_here = True
        proposal = transaction.proposal
        self._epoch_floor = proposal.epoch - 1  # the proposed epoch itself is committed
        published = self._publish(
            proposal.active,
            proposal.requester,
            proposal.reason,
            now,
            proposal.epoch - 1,
            transaction.explicit,
        )
        # The second phase waits for the acknowledgements as a synchronous activation does,
        # until the same deadline: the command's timeout bounds it as a whole.
        self._pending.append(
            PendingActivation(
                command=transaction.command,
                state=self._state,
                started=transaction.started,
                deadline=transaction.deadline,
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
