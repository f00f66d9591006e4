"""What the manager does with rule firings, as pure logic (the live manager and the offline
replay share it, so a replay makes the switches the manager made).

- Firings of one evaluation that contradict an earlier-declared rule's are overridden.
- A firing the manager refused (a relation, say) is tried again after each new state, until
  it succeeds, its rule fires anew, or a manual command (a state no rule caused) comes: that
  command stands until a rule's condition changes (docs/rules.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from contextros.rules.engine import Firing, Relations, resolve


class FiringQueue:
    """Turns firings into commands (`send`) and keeps the refused ones for the next state."""

    def __init__(
        self,
        rule_names: Iterable[str],
        send: Callable[[Firing], object],
        relations: Callable[[], Relations],
        note: Callable[[str], object] = lambda text: None,
        *,
        automatic_requesters: Iterable[str] = (),
    ) -> None:
        self._send_command = send
        self._relations = relations
        self._note = note
        # States these requesters caused are not manual commands (the rules, recovery).
        self._automatic = {f"rule {name}" for name in rule_names} | set(automatic_requesters)
        self._refused: dict[str, Firing] = {}
        self._manual_states = 0  # states published that no rule caused, so far
        self._submitted_at: dict[str, int] = {}  # rule -> _manual_states when it last fired
        self.last: dict[str, tuple[str, str]] = {}  # rule -> (its last firing, the outcome)

    def fire(self, firings: list[Firing]) -> None:
        """Firings of one evaluation (or one tick)."""
        if not firings:
            return
        if len(firings) > 1:
            firings, overridden = resolve(firings, self._relations())
            for firing in overridden:
                self._note(
                    f"{firing.requester} ({firing.reason}) overridden by a rule declared "
                    "before it (contradicting targets)"
                )
        for firing in firings:
            self._refused.pop(firing.rule, None)  # superseded by the rule's new value
            self._send(firing)

    def outcome(self, firing: Firing, text: str) -> None:
        self.last[firing.rule] = (asked(firing), text)

    def refused(self, firing: Firing) -> None:
        """The manager refused `firing`: keep it for the next state (unless newer), unless a
        manual command set a state since it was submitted (that command stands)."""
        if self._submitted_at.get(firing.rule, self._manual_states) != self._manual_states:
            self._dropped(firing)
            return
        self._refused.setdefault(firing.rule, firing)

    def published(self, requester: str) -> None:
        """A state was published. One that no rule and no recovery caused is a manual
        command: it stands until a rule's condition changes, so the refused firings, older
        than it, are dropped."""
        if requester in self._automatic:
            return
        self._manual_states += 1
        for firing in self._refused.values():
            self._dropped(firing)
        self._refused.clear()

    def retry(self) -> None:
        """A new state: the refused firings may pass now (in file order)."""
        waiting = sorted(self._refused.values(), key=lambda f: f.priority)
        self._refused.clear()
        for firing in waiting:
            self._send(firing)

    def _send(self, firing: Firing) -> None:
        self._submitted_at[firing.rule] = self._manual_states
        self.last[firing.rule] = (asked(firing), "waiting for the manager")
        self._send_command(firing)

    def _dropped(self, firing: Firing) -> None:
        self._note(
            f"{firing.requester}: its refused firing is dropped, a manual command came after "
            "it (it acts again when its condition changes)"
        )


def asked(firing: Firing) -> str:
    """What a firing asks for, in words ("activate Outdoor")."""
    parts = [f"activate {', '.join(firing.activate)}"] if firing.activate else []
    parts += [f"deactivate {', '.join(firing.deactivate)}"] if firing.deactivate else []
    return " and ".join(parts)
