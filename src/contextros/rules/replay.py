"""Rules evaluated offline over recorded messages, with the manager's own logic.

The rule engine, the firing queue (overrides, refused firings tried again, manual commands
standing) and the manager's protocol (validation, groups, relations, epochs) are the very
code the Layer manager runs; only the clock is the recording's: each message at its log
time, and the manager's timer every `tick_period` between them (a hold time ends at the
first tick after it, as live). Commands are asynchronous here, so a switch takes effect at
once instead of after the nodes' acknowledgements (milliseconds live).

States in the recording that no rule caused (an operator's commands) are played too: they
are part of the context the rules saw.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    ParticipantReport,
    PublishState,
    Reply,
)
from contextros.protocol.manager import RECOVERY_REQUESTER, ManagerProtocol, ManagerSettings
from contextros.protocol.relations import LayerDeclaration, merge_declarations
from contextros.rules.engine import Firing, RuleEngine
from contextros.rules.firings import FiringQueue, asked
from contextros.rules.ruleset import RuleSet

MANAGER_TICK = 0.05  # the manager node's timer period (LayerManagerNode's tick_period)
REPLAY_REQUESTER = "recording"  # the state the recording started in


@dataclass(frozen=True)
class Switch:
    """A state the replayed manager published."""

    time: float
    epoch: int
    active: tuple[str, ...]
    requester: str  # "rule NAME", or who asked in the recording
    reason: str


@dataclass(frozen=True)
class Refusal:
    time: float
    rule: str
    asked: str
    message: str


@dataclass
class ReplayResult:
    switches: list[Switch] = field(default_factory=list)
    refusals: list[Refusal] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # Each field a rule reads: its numeric values over time (for the timeline).
    signals: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    # (rule, start, end) of each hold time that ended in a firing.
    holds: list[tuple[str, float, float]] = field(default_factory=list)
    # Each rule topic's first message in the recording: the rules saw nothing before it.
    first_inputs: dict[str, float] = field(default_factory=dict)


class RuleReplay:
    """Feed it messages (`message`) and recorded manual states (`manual`) in time order,
    then `finish`; `result` holds the switches it made."""

    def __init__(
        self,
        rules: RuleSet,
        declarations: Iterable[LayerDeclaration] = (),
        *,
        start: float,
        active: Sequence[str] = (),
        tick_period: float = MANAGER_TICK,
    ) -> None:
        self.rules = rules
        self.engine = RuleEngine(rules)
        self.result = ReplayResult()
        self._tick_period = tick_period
        self._next_tick = start
        self._now = start
        declared = merge_declarations(
            [
                *declarations,
                *(LayerDeclaration(n) for r in rules.rules for n in r.targets()),
                *(LayerDeclaration(n) for n in active),  # someone implemented them
            ]
        )
        settings = ManagerSettings(
            manager_id="replay",
            liveness_timeout=math.inf,
            recovery_window=0.0,
            recovery_quiet=0.0,
            heartbeat_period=math.inf,
            unknown_layer_grace=0.0,
        )
        self.protocol = ManagerProtocol(start, settings, None)
        self.queue = FiringQueue(
            [rule.name for rule in rules.rules],
            self._send,
            self._relations,
            self.result.notes.append,
            automatic_requesters=(RECOVERY_REQUESTER,),
        )
        self._replies: dict[int, ActivationResult] = {}
        self._next_request = 0
        # One participant that implements every layer: validation sees all declarations.
        everything = ParticipantReport(
            node="/replay", incarnation="replay", layers=tuple(declared.values())
        )
        self.protocol.receive_status(everything, start)
        self._run(self.protocol.tick(start))
        self._retried_at = self.protocol.state.epoch
        self._getters = {
            ref.text: (ref.topic, operator.attrgetter(".".join(ref.path)))
            for rule in rules.rules
            for ref in rule.fields
        }
        self._hold = {rule.name: rule.hold for rule in rules.rules}
        if active:
            self._command(tuple(active), (), REPLAY_REQUESTER, "the state the recording began in")

    # -- input --------------------------------------------------------------------------

    def message(self, time: float, topic: str, message: Any) -> None:
        """A message on a rule's topic (the name as the rules write it)."""
        self._advance(time)
        self.result.first_inputs.setdefault(topic, time)
        self._sample(time, topic, message)
        firings = self.engine.on_message(topic, message, time)
        for failure in self.engine.failures:
            self.result.notes.append(f"{failure} (at {time:.3f})")
        self.engine.failures.clear()
        self._fire(firings)

    def manual(self, time: float, active: Sequence[str], requester: str, reason: str) -> None:
        """A state of the recording that no rule caused: the same command again."""
        self._advance(time)
        current = self.protocol.state.active
        off = tuple(name for name in current if name not in active)
        self._command(tuple(active), off, requester, reason)

    def finish(self, time: float) -> ReplayResult:
        self._advance(time)
        return self.result

    # -- the manager's loop ---------------------------------------------------------------

    def _advance(self, time: float) -> None:
        """The manager's timer up to `time`: hold times that end, refused firings retried."""
        while self._next_tick <= time:
            self._now = self._next_tick
            self._run(self.protocol.tick(self._now))
            self._fire(self.engine.tick(self._now))
            if self._retried_at != self.protocol.state.epoch:
                self._retried_at = self.protocol.state.epoch
                self.queue.retry()
            self._next_tick += self._tick_period
        self._now = time

    def _fire(self, firings: list[Firing]) -> None:
        for firing in firings:
            hold = self._hold.get(firing.rule, 0.0)
            if hold:
                self.result.holds.append((firing.rule, self._now - hold, self._now))
        self.queue.fire(firings)

    def _send(self, firing: Firing) -> None:
        reply = self._command(firing.activate, firing.deactivate, firing.requester, firing.reason)
        if reply.success:
            self.queue.outcome(firing, reply.message)
            return
        self.queue.outcome(firing, f"refused: {reply.message}")
        self.result.refusals.append(Refusal(self._now, firing.rule, asked(firing), reply.message))
        self.queue.refused(firing)

    def _command(
        self, activate: tuple[str, ...], deactivate: tuple[str, ...], requester: str, reason: str
    ) -> ActivationResult:
        """An asynchronous command: published (or refused) at once."""
        self._next_request += 1
        command = ActivationCommand(
            self._next_request, activate, deactivate, requester=requester, reason=reason
        )
        self._run(self.protocol.receive_command(command, self._now))
        return self._replies.pop(command.request_id)

    def _run(self, actions: list[ManagerAction]) -> None:
        for action in actions:
            if isinstance(action, PublishState):
                state = action.state
                if state.requester != RECOVERY_REQUESTER:  # the replay's own start
                    self.result.switches.append(
                        Switch(self._now, state.epoch, state.active, state.requester, state.reason)
                    )
                self.queue.published(state.requester)
            elif isinstance(action, Reply):
                self._replies[action.request_id] = action.result

    def _relations(self) -> dict[str, tuple[frozenset[str], frozenset[str]]]:
        return {
            name: (declaration.groups, declaration.excludes)
            for name, declaration in self.protocol.declarations().items()
        }

    def _sample(self, time: float, topic: str, message: Any) -> None:
        for text, (field_topic, getter) in self._getters.items():
            if field_topic != topic:
                continue
            try:
                value = getter(message)
            except AttributeError:
                continue
            if isinstance(value, bytes) and len(value) == 1:
                value = value[0]
            if isinstance(value, bool | int | float):
                self.result.signals.setdefault(text, []).append((time, float(value)))


def declarations_from_files(paths: Iterable[str]) -> list[LayerDeclaration]:
    """The layers and relations that layer files declare (groups, excludes, requires,
    after), as the participants built from them would register them."""
    from contextros.language.flavours import parse_files

    parsed, _ = parse_files(paths)
    found: list[LayerDeclaration] = []
    for _, _, layer_file in parsed:
        for group in layer_file.groups:
            found += [LayerDeclaration(m.name, group=group.name) for m in group.members]
        for layer in layer_file.layers:
            found.append(
                LayerDeclaration(
                    layer.name,
                    excludes=frozenset(r.name for r in layer.excludes),
                    requires=frozenset(r.name for r in layer.requires),
                    after=frozenset(r.name for r in layer.after),
                )
            )
    return found


def declaration_from_recorded(info: Any) -> LayerDeclaration:
    """A LayerInfo of a recorded participant status (decoded, fields as attributes)."""
    return LayerDeclaration(
        str(info.name),
        excludes=frozenset(map(str, info.excludes)),
        requires=frozenset(map(str, info.required)),
        group=str(info.group),
        after=frozenset(map(str, info.after)),
    )
