"""The Layer manager as a pure state machine: events in, actions out, time passed in."""

from __future__ import annotations

from contextros.protocol.events import (
    ActivationCommand,
    ManagerAction,
    ParticipantJoined,
    ParticipantReport,
    PublishProposal,
    Reply,
)
from contextros.protocol.manager.acknowledgements import Acknowledgements
from contextros.protocol.manager.atomic_votes import AtomicVotes
from contextros.protocol.manager.command_queue import CommandQueue
from contextros.protocol.manager.records import ParticipantRecord
from contextros.protocol.manager.recovery import Recovery
from contextros.protocol.manager.registry import Registry
from contextros.protocol.validation import command_problems


class ManagerProtocol(Registry, CommandQueue, Acknowledgements, AtomicVotes, Recovery):
    """The manager's registry, state and pending synchronous activations: the events it
    takes (statuses, commands, the passing of time) and the actions it returns."""

    def receive_status(self, report: ParticipantReport, now: float) -> list[ManagerAction]:
        self._order_cache = None
        if self._heard_again(report, now):
            return []
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
        elif known.presumed:  # known from the state file, heard again
            actions.append(ParticipantJoined(report.node))
        if known is None or known.report.layers != report.layers:
            self._declarations_cache = None
        self._participants[key] = ParticipantRecord(report, last_heard=now)
        self._hosted[report.node] = report.hosted
        if report.node in self._dropped:  # it rejoined: the dropped list names absent nodes
            self._dropped.remove(report.node)
            if known is None:
                self._await_rejoined(key)
        if not self.recovering and self._is_ahead(report):
            actions += self._overtake(report, now)
        if known is None:
            actions += self._release_held(now)
        actions += self._settle_pending(now, examine=(key,))
        actions += self._count_votes(now, voter=key if known is not None else None)
        return actions

    def _heard_again(self, report: ParticipantReport, now: float) -> bool:
        """A heartbeat repeating the status last accepted, with no activation waiting: it
        only proves the node alive (what it says was validated when first heard)."""
        node, incarnation = report.node, report.incarnation
        if type(node) is not str or type(incarnation) is not str or self._pending:
            return False
        known = self._participants.get((node, incarnation))
        if known is None or known.presumed or self._transaction is not None:
            return False
        if known.report != report:
            return False
        known.last_heard = now
        return True

    def receive_command(
        self,
        command: ActivationCommand,
        now: float,
        received: float | None = None,
        *,
        started: bool = False,
    ) -> list[ManagerAction]:
        """A command, received at `received` (default `now`; earlier when the adapter had
        work to do first, such as the layers' ROS side): its timeout and its answer's
        `elapsed` count from there. `started`: the adapter began its work (set the
        parameters and lifecycle states) before its deadline, so it is carried through,
        never refused as expired: ROS has changed already."""
        self._order_cache = None
        received = now if received is None else received
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
            if refusal := self._expired(command, now, received):
                return refusal
            self._queued.append((command, received))
            return []
        return self._execute(command, now, received, started)

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

    def expired(self, command: ActivationCommand, now: float, received: float) -> bool:
        """Whether `command`, received at `received`, is past its deadline (its caller has
        given up): `receive_command` would refuse it, nothing changed."""
        return now >= self._deadline(command, received)

    def refusal_if_expired(
        self, command: ActivationCommand, now: float, received: float, waiting_for: str
    ) -> list[ManagerAction]:
        """The refusal of `command` (kept by the adapter, waiting for `waiting_for`) if its
        deadline passed, else []."""
        return self._expired(command, now, received, waiting_for)

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
        actions: list[ManagerAction] = self._expire_waiting(now)
        self._adapt_status_period(now)
        if self._recovering_until is not None and now >= self._recovering_until:
            actions += self._finish_recovery(now)
        if self._recovering_until is None:
            actions += self._drop_silent(now)
            actions += self._release_held(now)
            actions += self._settle_pending(now, examine=())  # only the deadlines changed
            actions += self._count_votes(now)
            if self._transaction is not None:  # repeated while the vote is open (lossy links)
                actions.append(PublishProposal(self._transaction.proposal))
        actions += self._heartbeat(now)
        return actions
