"""Rule evaluation as a pure state machine: messages and time in, activations out.

No ROS inside (sans-I/O, like the manager's protocol): the adapter feeds the latest message
of each topic and the clock, and turns each `Firing` into an ordinary activation command.
Conditions are compiled once into closures over `operator` functions, so an evaluation is a
few attribute reads and comparisons (benchmarks/rules.py measures it).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from contextros.language.rules import (
    BoolOp,
    Comparison,
    Condition,
    FieldRef,
    GraphRef,
    Literal,
    Not,
    RuleDecl,
    condition_text,
    relaxed,
)
from contextros.protocol.validation import MAX_TEXT_LENGTH
from contextros.rules.contradictions import Relations as Relations  # (firings.py)
from contextros.rules.ruleset import RuleSet

_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "==": operator.eq,
    "!=": operator.ne,
}

Latest = Mapping[str, Any]
Evaluator = Callable[[Latest], bool]


class _NoData(Exception):
    """A topic the condition reads has not delivered a message yet, or a lifecycle state or
    parameter it reads has no value (its node is absent, or has no such parameter)."""


@dataclass(frozen=True)
class RuleReport:
    """What one rule is doing now (for `status` and the dashboard): its condition's value on
    the latest messages, the value in force, the hold timer and the hysteresis state."""

    name: str
    where: str
    text: str
    value: bool | None  # None: a topic it reads has not delivered yet (or the rule is off)
    settled: bool | None  # the value that lasted its hold time (None: none yet)
    holding: bool  # a new value waits out the hold time
    hold_left: float
    hold: float
    hysteresis: float
    relaxed: bool  # the hysteresis thresholds apply now (a 'while' rule that holds)
    readings: tuple[tuple[str, str], ...]  # (field, its latest value) for each field read
    error: str | None  # why the rule is off

    @property
    def value_text(self) -> str:
        if self.error is not None:
            return "off"
        return "no data" if self.value is None else str(self.value).lower()


@dataclass(frozen=True)
class Firing:
    """A rule acting: activate and deactivate these layers, for this reason."""

    rule: str
    activate: tuple[str, ...]
    deactivate: tuple[str, ...]
    reason: str
    priority: int  # the rule's place in its files: the first wins a contradiction

    @property
    def requester(self) -> str:
        return f"rule {self.rule}"


def _operand(operand: FieldRef | Literal | GraphRef) -> Callable[[Latest], Any]:
    if isinstance(operand, Literal):
        value = operand.value
        return lambda latest: value
    if isinstance(operand, GraphRef):
        return _graph_value(operand.text)
    topic, getter = operand.topic, operator.attrgetter(".".join(operand.path))

    def read(latest: Latest) -> Any:
        message = latest.get(topic)
        if message is None:
            raise _NoData(topic)
        value = getter(message)
        if type(value) is bytes and len(value) == 1:
            return value[0]  # a ROS byte (octet) arrives from rclpy as bytes: its number
        return value

    return read


def _graph_value(source: str) -> Callable[[Latest], Any]:
    """A lifecycle state or a parameter: the plain value itself is the engine's input."""

    def read(latest: Latest) -> Any:
        value = latest.get(source)
        if value is None:
            raise _NoData(source)
        return value

    return read


def compile_condition(condition: Condition, margin: float = 0.0, sign: float = 1.0) -> Evaluator:
    """A closure computing `condition` from the latest message of each topic. With `margin`,
    thresholds against numbers move by it so that the condition holds longer (hysteresis,
    `contextros.language.rules.relaxed`)."""
    return _compiled(relaxed(condition, margin, sign))


def _compiled(condition: Condition) -> Evaluator:
    if isinstance(condition, Not):
        inner = _compiled(condition.operand)
        return lambda latest: not inner(latest)
    if isinstance(condition, BoolOp):
        parts = [_compiled(c) for c in condition.operands]
        combined = parts[0]
        for part in parts[1:]:  # nested closures short-circuit like the Python operators
            combined = _both(combined, part) if condition.op == "and" else _either(combined, part)
        return combined
    return _comparison(condition)


def _both(first: Evaluator, second: Evaluator) -> Evaluator:
    return lambda latest: first(latest) and second(latest)


def _either(first: Evaluator, second: Evaluator) -> Evaluator:
    return lambda latest: first(latest) or second(latest)


def _comparison(condition: Comparison) -> Evaluator:
    left = _operand(condition.left)
    if condition.right is None:
        return lambda latest: bool(left(latest))
    right = _operand(condition.right)
    compare = _OPERATORS[condition.op]
    return lambda latest: compare(left(latest), right(latest))


class RuleFailed(Exception):
    """Evaluating a rule raised (a message unlike what its type promised): the rule is off."""

    def __init__(self, rule: RuleDecl, where: str, why: str) -> None:
        super().__init__(f"rule {rule.name} ({where}) is off: evaluating it failed: {why}")
        self.rule = rule
        self.where = where
        self.why = why


class _RuleState:
    """One rule's settled value and the candidate value waiting out the hold time."""

    def __init__(self, rule: RuleDecl, where: str, priority: int) -> None:
        self.rule = rule
        self.where = where
        self.priority = priority
        self.strict = compile_condition(rule.condition)
        self.relaxed = (
            compile_condition(rule.condition, rule.hysteresis)
            if rule.hysteresis and rule.mode == "while"
            else self.strict
        )
        self.text = condition_text(rule.condition)
        self.settled: bool | None = None
        self.candidate: bool | None = None
        self.since = 0.0
        self.failed: str | None = None  # why the rule is off (its evaluation raised)

    def evaluate(self, latest: Latest, now: float) -> Firing | None:
        if self.failed is not None:
            return None
        try:
            value = (self.relaxed if self.settled else self.strict)(latest)
        except _NoData:
            return None
        except Exception as error:  # a message the static checks could not foresee
            self.failed = f"{type(error).__name__}: {error}"
            self.candidate = None
            raise RuleFailed(self.rule, self.where, self.failed) from error
        if value == self.settled:
            self.candidate = None
            return None
        if value != self.candidate:
            self.candidate, self.since = value, now
        return self.tick(now)

    def report(self, latest: Latest, now: float) -> RuleReport:
        relaxed = bool(self.settled) and self.relaxed is not self.strict
        value: bool | None = None
        if self.failed is None:
            try:
                value = (self.relaxed if self.settled else self.strict)(latest)
            except _NoData:
                value = None
            except Exception:  # the next evaluation reports it, not this look
                value = None
        readings = []
        refs: list[FieldRef | GraphRef] = [*self.rule.fields, *self.rule.graph]
        for ref in {ref.text: ref for ref in refs}.values():
            try:
                shown = repr(_operand(ref)(latest))
            except _NoData:
                shown = "no message yet" if isinstance(ref, FieldRef) else "no value"
            except Exception as error:  # a field the message lacks
                shown = f"unreadable ({type(error).__name__})"
            readings.append((ref.text, shown))
        holding = self.candidate is not None
        return RuleReport(
            name=self.rule.name,
            where=self.where,
            text=self.rule.text,
            value=value,
            settled=self.settled,
            holding=holding,
            hold_left=max(0.0, self.rule.hold - (now - self.since)) if holding else 0.0,
            hold=self.rule.hold,
            hysteresis=self.rule.hysteresis if self.rule.mode == "while" else 0.0,
            relaxed=relaxed,
            readings=tuple(readings),
            error=self.failed,
        )

    def tick(self, now: float) -> Firing | None:
        # (a nanosecond of slack: a clock's float sums must not cost a whole period)
        if self.candidate is None or now - self.since < self.rule.hold - 1e-9:
            return None
        self.settled, self.candidate = self.candidate, None
        return self._fire(self.settled)

    def _fire(self, holds: bool) -> Firing | None:
        rule = self.rule
        held = f" for {rule.hold:g} s" if rule.hold else ""
        truth = f"{self.text}{held}" if holds else f"not ({self.text}){held}"
        # A command's reason is at most MAX_TEXT_LENGTH characters: a long condition is
        # cut, never the place it is declared.
        place = f" ({self.where})"
        room = MAX_TEXT_LENGTH - len(place)
        reason = (truth if len(truth) <= room else truth[: room - 3] + "...") + place
        layer = rule.layer.name
        if rule.mode == "activate":
            return Firing(rule.name, (layer,), (), reason, self.priority) if holds else None
        if rule.mode == "deactivate":
            return Firing(rule.name, (), (layer,), reason, self.priority) if holds else None
        if holds:
            return Firing(rule.name, (layer,), (), reason, self.priority)
        if rule.otherwise is not None:
            return Firing(rule.name, (rule.otherwise.name,), (), reason, self.priority)
        return Firing(rule.name, (), (layer,), reason, self.priority)


class RuleEngine:
    """Evaluates a rule set: `on_message` for each message, `tick` as time passes."""

    def __init__(self, rules: RuleSet) -> None:
        self.rules = rules
        self._states = [
            _RuleState(rule, rules.where(rule), index) for index, rule in enumerate(rules.rules)
        ]
        self._latest: dict[str, Any] = {}
        # Rules whose evaluation raised, each reported once: they stay off, the others run.
        self.failures: list[RuleFailed] = []
        # Each input (a topic, or a graph value's `GraphRef.text`) -> the rules reading it.
        self._by_topic: dict[str, list[_RuleState]] = {}
        for state in self._states:
            inputs = [ref.topic for ref in state.rule.fields]
            inputs += [ref.text for ref in state.rule.graph]
            for name in dict.fromkeys(inputs):
                self._by_topic.setdefault(name, []).append(state)

    def topics(self) -> tuple[str, ...]:
        """The topics the rules read (the graph's values come through `on_value`)."""
        return self.rules.topics()

    def on_value(self, source: str, value: Any, now: float) -> list[Firing]:
        """A lifecycle state or parameter value (`source` is its `GraphRef.text`): evaluate
        the rules reading it, as `on_message` does. None: it has no value now (its node left
        the graph, the parameter was deleted): those rules' conditions are unknown, as
        before a topic's first message, so they keep the value in force and a change
        waiting out its hold time is dropped (docs/rules.md, "The ROS graph's state")."""
        if value is not None:
            return self.on_message(source, value, now)
        self._latest.pop(source, None)
        for state in self._by_topic.get(source, ()):
            state.candidate = None
        return []

    def on_message(self, topic: str, message: Any, now: float) -> list[Firing]:
        """The latest message on `topic`: evaluate the rules that read it. A rule whose
        evaluation raises is turned off and added to `failures`; the others still run."""
        self._latest[topic] = message
        firings = []
        for state in self._by_topic.get(topic, ()):
            try:
                firing = state.evaluate(self._latest, now)
            except RuleFailed as failure:
                self.failures.append(failure)
                continue
            if firing is not None:
                firings.append(firing)
        return firings

    def report(self, now: float) -> list[RuleReport]:
        """Every rule's current value, hold timer and hysteresis state, in file order."""
        return [state.report(self._latest, now) for state in self._states]

    def tick(self, now: float) -> list[Firing]:
        """Rules whose condition kept its new value for the hold time, without a message."""
        firings = []
        for state in self._states:
            if state.candidate is not None:
                firing = state.tick(now)
                if firing is not None:
                    firings.append(firing)
        return firings


def resolve(firings: list[Firing], relations: Relations) -> tuple[list[Firing], list[Firing]]:
    """Firings of one evaluation that contradict an earlier-declared one are overridden:
    the same layer on and off, two members of an exclusive group, two excluding layers.
    Returns (kept, overridden); deterministic (file order)."""
    kept: list[Firing] = []
    overridden: list[Firing] = []
    for firing in sorted(firings, key=lambda f: f.priority):
        if any(_contradict(firing, earlier, relations) for earlier in kept):
            overridden.append(firing)
        else:
            kept.append(firing)
    return kept, overridden


def _contradict(a: Firing, b: Firing, relations: Relations) -> bool:
    if set(a.activate) & set(b.deactivate) or set(a.deactivate) & set(b.activate):
        return True
    for x in a.activate:
        groups_x, excludes_x = relations.get(x, (frozenset(), frozenset()))
        for y in b.activate:
            if x == y:
                continue
            groups_y, excludes_y = relations.get(y, (frozenset(), frozenset()))
            if groups_x & groups_y or y in excludes_x or x in excludes_y:
                return True
    return False
