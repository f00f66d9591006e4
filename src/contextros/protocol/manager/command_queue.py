"""Commands: validated against the live declarations, then executed in arrival order.

A command that cannot be decided yet waits: during recovery (`_queued`), behind an open
atomic vote (`_behind_transaction`, see atomic_votes.py) or, within the grace period after
recovery, for a participant implementing a layer nobody declared yet (`_held`). At most
`max_waiting_commands` wait in all. The next configuration is composed as the core's
`switch` does, then ordered as the declared `after` relations say.
"""

from __future__ import annotations

from contextros.protocol.events import ActivationCommand, ActivationResult, ManagerAction, Reply
from contextros.protocol.manager.base import NO_CHANGE, ManagerBase
from contextros.protocol.manager.records import PendingActivation
from contextros.protocol.relations import (
    DeclaredOrder,
    LayerDeclaration,
    Switched,
    declared_order,
    implication_problems,
    implied_by,
    implied_layers,
    order_note,
    relation_violations,
    switched,
)
from contextros.protocol.validation import listing


class CommandQueue(ManagerBase):
    """Validation and execution of commands, and the commands waiting to be decided."""

    @property
    def waiting_commands(self) -> int:
        """Commands received and not answered yet (bounded by `max_waiting_commands`)."""
        waiting = len(self._pending) + len(self._queued) + len(self._held)
        return waiting + len(self._behind_transaction) + (self._transaction is not None)

    def _expired(
        self,
        command: ActivationCommand,
        now: float,
        received: float,
        waiting_for: str | None = None,
    ) -> list[ManagerAction]:
        """The refusal of `command` if its deadline passed while it waited, else [];
        `waiting_for` says what it waited for (default: what the protocol holds it for)."""
        deadline = self._deadline(command, received)
        if now < deadline:
            return []
        why = waiting_for or self._waiting_for()
        message = (
            f"not started within the command's timeout ({deadline - received:g} s): it waited "
            f"{now - received:.1f} s in the manager ({why}); nothing changed"
        )
        result = ActivationResult(
            False, message, self._state.epoch, self._state.active, elapsed=now - received
        )
        return [Reply(command.request_id, result)]

    def _waiting_for(self) -> str:
        if self.recovering:
            return "recovering after its start"
        if self._transaction is not None:
            return f"behind the atomic vote on epoch {self._transaction.proposal.epoch}"
        return "for a participant implementing its layers"

    def _expire_waiting(self, now: float) -> list[ManagerAction]:
        """Refuse the waiting commands whose callers gave up (their deadline passed)."""
        actions: list[ManagerAction] = []
        for waiting in (self._queued, self._held, self._behind_transaction):
            kept = []
            for command, received in waiting:
                refusal = self._expired(command, now, received)
                actions += refusal
                if not refusal:
                    kept.append((command, received))
            waiting[:] = kept
        return actions

    def _execute(
        self, command: ActivationCommand, now: float, received: float, started: bool = False
    ) -> list[ManagerAction]:
        if not started and (refusal := self._expired(command, now, received)):
            return refusal
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
        explicit = self._switch(command)[1].explicit
        changes = new_active != self._state.active or self._state.epoch == 0
        if command.atomic and changes:
            return self._propose(command, new_active, now, received, explicit)
        note = self._order_note(command)
        actions: list[ManagerAction] = []
        if not changes:
            self._explicit = explicit  # (de)activating a layer also implied keeps it active
        if changes:
            self._decided_here = True
            actions.append(
                self._publish(
                    new_active, command.requester, command.reason, now, self._state.epoch, explicit
                )
            )
        if not command.synchronous and not command.atomic:  # (atomic, no change: as sync)
            message = f"epoch {self._state.epoch} published{note}" if actions else NO_CHANGE
            return [*actions, Reply(command.request_id, self._result(True, message))]
        self._pending.append(
            PendingActivation(
                command=command,
                state=self._state,
                started=received,
                deadline=self._deadline(command, received),
                waiting=set(self._participants),
                changed=bool(actions),
                note=note,
            )
        )
        return actions + self._settle_pending(now)

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
        # The activated layers that imply others (most imply nothing: one look-up each).
        implying = [
            name
            for name in dict.fromkeys(command.activate)
            if declarations[name].implies  # (each is known: checked above)
        ]
        implied_unknown = {
            implied: name
            for name in implying
            for implied in implied_layers(name, declarations)
            if implied not in declarations
        }
        if implied_unknown:
            names = ", ".join(f"{i!r} (implied by {n})" for i, n in implied_unknown.items())
            message = f"unknown layer {names}: no live participant implements it; nothing changed"
            return message, True
        rivals = _group_rivals(command.activate, declarations)
        if rivals:
            return f"relation violated: {rivals}; activate only one of them; nothing changed", False
        contradictions = [
            problem for name in implying for problem in implication_problems(name, declarations)
        ]
        if contradictions:
            return (
                f"contradicting declarations: {'; '.join(contradictions[:5])}; nothing changed",
                False,
            )
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
            causes += _implied_note(order.layers, declarations, introduced)
            return (
                f"relation violated: {'; '.join(introduced[:5])}{causes}; nothing changed",
                False,
            )
        kept = self._switch(command)[1].layers
        still = [name for name in dict.fromkeys(command.deactivate) if name in kept]
        if still:
            by = implied_by(kept, declarations)
            held = "; ".join(
                f"{name} is implied by {', '.join(by.get(name, ()))}" for name in still
            )
            return (
                f"cannot deactivate: {held}, which stays active; deactivate that instead; "
                "nothing changed",
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
        return self._switch(command)[0]

    def _switch(self, command: ActivationCommand) -> tuple[DeclaredOrder, Switched]:
        # Asked several times while one command is validated and executed: computed once per
        # command and state (the cache is dropped by every event, see `_fresh`).
        cached = self._order_cache
        if cached is not None and cached[0] is command and cached[1] == self._state.epoch:
            return cached[2], cached[3]
        declarations = self.declarations()
        # As the core's `switch` (relations.switched), with what the layers imply.
        result = switched(
            self._state.active,
            self._explicit,
            command.activate,
            command.deactivate,
            declarations,
        )
        order = declared_order(result.layers, declarations)
        self._order_cache = (command, self._state.epoch, order, result)
        return order, result


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


def _implied_note(
    active: tuple[str, ...], declarations: dict[str, LayerDeclaration], problems: list[str]
) -> str:
    """' (CameraHigh implied by Flight)' for the implied layers the problems name."""
    by = implied_by(active, declarations)
    named = {word.strip(",;'") for problem in problems for word in problem.split()}
    notes = [f"{name} implied by {', '.join(by[name])}" for name in sorted(named) if name in by]
    return f" ({'; '.join(notes[:5])})" if notes else ""
