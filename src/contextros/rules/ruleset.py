"""A set of context rules, from layer files or the Python API, with its static checks."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from contextros.language.checker import check as check_layer_file
from contextros.language.diagnostics import (
    Diagnostic,
    DiagnosticSink,
    LayerSyntaxError,
    sorted_diagnostics,
)
from contextros.language.flavours import parse_files
from contextros.language.positions import Position, Ref
from contextros.language.rules import (
    BoolOp,
    Comparison,
    Condition,
    FieldRef,
    Literal,
    Not,
    RuleDecl,
    parse_rule,
    relaxed,
)
from contextros.language.topics import TopicDecl

# What a message field is, as far as a condition cares: "number", "string", "bool",
# "message" (has fields of its own), "array" (not comparable), or None (no such field).
FieldKind = str | None
# Looks up the kind of a field path in the message type of one topic.
FieldLookup = Callable[[tuple[str, ...]], FieldKind]
# The field lookup of a message type named PACKAGE/msg/NAME; raises ValueError saying why
# when the type is not available here (NoSuchMessageType when its package is there but has
# no such type). The rules never import a message package themselves: the caller passes
# this in (`contextros check` and the manager pass the installed interfaces').
MessageTypes = Callable[[str], FieldLookup]


class NoSuchMessageType(ValueError):
    """A `MessageTypes` lookup found the type's package but no such type in it: a misspelt
    name (`sensor_msgs/msg/BateryState`), an error wherever it is checked. A package not
    installed here is a plain ValueError: the robot may have it."""


@dataclass(frozen=True)
class Rule:
    """A rule of the Python API: `Rule("Battery", "LowBattery while battery.percentage < 20
    for 2 s hysteresis 5")`, the same text a layer file takes after `rule NAME:`."""

    name: str
    text: str


class RuleSet:
    """Parsed rules plus where they came from, so that every later error (a field the topic's
    message type does not have) still points at file:line:col with a caret."""

    def __init__(
        self,
        rules: Sequence[RuleDecl],
        sources: Mapping[str, str],
        topics: Sequence[TopicDecl] = (),
    ) -> None:
        self.rules = tuple(rules)
        self._sources = dict(sources)  # path -> text
        # `topic NAME: TYPE` declarations, in file order (conflicts: see check()).
        self.declarations = tuple(topics)
        self.topic_types: dict[str, TopicDecl] = {}
        for declaration in self.declarations:
            self.topic_types.setdefault(declaration.topic, declaration)

    # -- construction -------------------------------------------------------------------

    @classmethod
    def from_files(
        cls,
        paths: Iterable[str | os.PathLike[str]],
        language: str | None = None,
        message_types: MessageTypes | None = None,
    ) -> RuleSet:
        """The rules of layer files (either flavour). Each file is checked as `contextros
        check` checks it (with `message_types`, the declared topics' fields too), then the
        files together (a rule name or a topic's type declared twice across them);
        LayerSyntaxError lists every error, file by file in the order given."""
        rules: list[RuleDecl] = []
        topics: list[TopicDecl] = []
        sources: dict[str, str] = {}
        parsed, errors = parse_files(paths, language)
        for name, source, layer_file in parsed:
            errors += [d for d in check_layer_file(layer_file, message_types) if d.is_error]
            rules += layer_file.rules
            topics += layer_file.topics
            sources[name] = source
        result = cls(rules, sources, topics)
        together = result.check()
        if message_types is not None:
            together += result.check_declared_fields(message_types)
        errors += [d for d in together if d.is_error]
        if errors:
            order = {name: index for index, name in enumerate(sources)}
            errors = sorted_diagnostics(errors)  # one of each (a file's own: found twice)
            errors.sort(key=lambda d: order.get(d.path, -1))  # stable: by line within a file
            raise LayerSyntaxError(errors)
        return result

    @classmethod
    def from_rules(cls, rules: Iterable[Rule], path: str = "<rules>") -> RuleSet:
        """Rules of the Python API, each read as the line `rule NAME: TEXT` of `path`."""
        rules = list(rules)
        decls: list[RuleDecl] = []
        source = "".join(f"rule {rule.name}: {rule.text}\n" for rule in rules)
        sink = DiagnosticSink(path, source)
        for row, rule in enumerate(rules, start=1):
            if not rule.name.isidentifier():
                sink.error(f"rule name {rule.name!r} is not an identifier", row, 6)
                continue
            name = Ref(rule.name, Position(row, 6))
            col = len(f"rule {rule.name}: ") + 1
            decl = parse_rule(name, rule.text, row, col, sink)
            if decl is not None:
                decls.append(decl)
        result = cls(decls, {path: source})
        errors = [d for d in [*sink.items, *result.check()] if d.is_error]
        if errors:
            raise LayerSyntaxError(errors)
        return result

    # -- positions ----------------------------------------------------------------------

    def where(self, rule: RuleDecl | TopicDecl) -> str:
        return f"{Path(rule.path).name}:{rule.at.line}"

    def sink_for(self, rule: RuleDecl | TopicDecl) -> DiagnosticSink:
        return DiagnosticSink(rule.path, self._sources.get(rule.path, ""))

    # -- static checks ------------------------------------------------------------------

    def topics(self) -> tuple[str, ...]:
        """Every topic the rules read, in order of first mention."""
        return tuple(dict.fromkeys(ref.topic for rule in self.rules for ref in rule.fields))

    def check(
        self, relations: Mapping[str, tuple[frozenset[str], frozenset[str]]] | None = None
    ) -> list[Diagnostic]:
        """Duplicate names, and pairs of rules that may hold at once while switching to
        contradicting targets (the same layer on and off, two layers of one group, or two
        that exclude each other). `relations` maps a layer to (its groups, what it
        excludes); without it only the same-layer contradiction is known."""
        found: list[Diagnostic] = []
        seen: dict[str, RuleDecl] = {}
        for rule in self.rules:
            first = seen.get(rule.name)
            if first is not None:
                sink = self.sink_for(rule)
                sink.error(
                    f"rule {rule.name!r} is already declared at {self.where(first)}",
                    rule.at.line,
                    rule.at.col,
                )
                found += sink.items
            seen.setdefault(rule.name, rule)
        found += self._check_declarations()
        for index, first in enumerate(self.rules):
            for second in self.rules[index + 1 :]:
                clash = _contradiction(first, second, relations or {})
                if clash:
                    only_relaxed = not _contradiction(first, second, relations or {}, False)
                    hysteresis = _through_hysteresis(first, second) if only_relaxed else ""
                    sink = self.sink_for(second)
                    sink.warning(
                        f"rules {first.name} ({self.where(first)}) and {second.name} may hold at "
                        f"the same time{hysteresis} and {clash}: when both fire together, "
                        f"{first.name} "
                        "(declared first) wins and the other is logged as overridden; make "
                        "their conditions exclusive",
                        second.at.line,
                        second.at.col,
                    )
                    found += sink.items
        return found

    def _check_declarations(self) -> list[Diagnostic]:
        """A topic declared with two types; a declared topic no rule reads (a misspelt name)."""
        found: list[Diagnostic] = []
        read = set(self.topics())
        for declaration in self.declarations:
            sink = self.sink_for(declaration)
            first = self.topic_types[declaration.topic]
            if first.type_name != declaration.type_name:
                sink.error(
                    f"topic '{declaration.topic}' is already declared as {first.type_name} at "
                    f"{self.where(first)}: a topic has one message type",
                    declaration.type_at.line,
                    declaration.type_at.col,
                )
            elif first is declaration and self.rules and declaration.topic not in read:
                sink.warning(
                    f"no rule reads topic '{declaration.topic}' (rules name their topics as "
                    "declared: 'battery' and '/battery' are different names here)",
                    declaration.at.line,
                    declaration.at.col,
                )
            found += sink.items
        return found

    def check_declared_fields(self, message_types: MessageTypes) -> list[Diagnostic]:
        """The field checks of `check_fields`, offline: each topic's type from its `topic`
        declaration, its fields from `message_types` (the same lookup the manager uses on
        the type it sees on the ROS graph, so the same errors, word for word). A declared
        type its installed package does not have is an error at the declaration. A rule on
        a topic not declared, or declared with a type whose package is not installed here,
        gets a note: its fields are checked by the manager at run time."""
        found: list[Diagnostic] = []
        lookups: dict[str, FieldLookup] = {}
        unknown: dict[str, str] = {}  # topic -> why its fields cannot be checked here
        for declaration in self.topic_types.values():
            try:
                lookups[declaration.topic] = message_types(declaration.type_name)
            except NoSuchMessageType as error:
                sink = self.sink_for(declaration)
                sink.error(
                    f"the declared type of topic '{declaration.topic}' does not exist: {error}",
                    declaration.type_at.line,
                    declaration.type_at.col,
                )
                found += sink.items
            except ValueError as error:
                unknown[declaration.topic] = (
                    f"its declared type {declaration.type_name} ({self.where(declaration)}) "
                    f"is not available here: {error}"
                )
        known: dict[str, tuple[FieldLookup, str]] = {}
        for topic in self.topics():
            if topic not in self.topic_types:
                unknown[topic] = f"it has no declaration ('topic {topic}: PACKAGE/msg/TYPE')"
            if topic not in lookups:
                continue  # not declared, not available (a note below) or misspelt (an error)
            type_name = self.topic_types[topic].type_name
            try:
                found += self.check_fields(topic, lookups[topic], type_name, known)
            except ValueError as error:  # a nested type not available here
                unknown[topic] = (
                    f"a type inside its declared type {type_name} is not available here: {error}"
                )
                continue
            known[topic] = (lookups[topic], type_name)
        for rule in self.rules:
            sink = self.sink_for(rule)
            first_refs: dict[str, FieldRef] = {}
            for ref in rule.fields:
                first_refs.setdefault(ref.topic, ref)
            for topic, ref in first_refs.items():
                if topic in unknown:
                    sink.note(
                        f"rule {rule.name}'s fields on topic '{topic}' are checked at run time, "
                        f"when the Layer manager sees the topic's type: {unknown[topic]}",
                        ref.at.line,
                        ref.at.col,
                    )
            found += sink.items
        return found

    def type_mismatch(self, topic: str, resolved: str, type_name: str) -> Diagnostic | None:
        """The error for `topic` published (as `resolved`) with `type_name` while declared
        with another type, at the declaration's type; None when they agree or it is not
        declared."""
        declaration = self.topic_types.get(topic)
        if declaration is None or declaration.type_name == type_name:
            return None
        users = [rule.name for rule in self.rules if any(r.topic == topic for r in rule.fields)]
        sink = self.sink_for(declaration)
        sink.error(
            f"topic {resolved} is published as {type_name}, but topic '{topic}' is declared "
            f"as {declaration.type_name}: the rules reading it ({', '.join(users)}) stay off",
            declaration.type_at.line,
            declaration.type_at.col,
        )
        return sink.items[0]

    def check_fields(
        self,
        topic: str,
        lookup: FieldLookup,
        type_name: str,
        known: Mapping[str, tuple[FieldLookup, str]] | None = None,
    ) -> list[Diagnostic]:
        """Errors for fields of `topic` its message type (`type_name`) does not have, or that
        a condition compares with a constant of another kind. A field compared with another
        field is checked once both types are known: fields of `topic` itself, or of the
        topics in `known` (topic -> (lookup, type name), those already checked)."""
        types = {**(known or {}), topic: (lookup, type_name)}
        found: list[Diagnostic] = []
        for rule in self.rules:
            sink = self.sink_for(rule)
            for comparison in _comparisons(rule.condition):
                pair = _field_pair_problem(comparison, topic, types)
                if pair:
                    ref, problem = pair
                    sink.error(problem, ref.at.line, ref.at.col)
                operands = [comparison.left, comparison.right]
                refs = [o for o in operands if isinstance(o, FieldRef) and o.topic == topic]
                for ref in refs:
                    kind = lookup(ref.path)
                    if kind is None:
                        sink.error(
                            f"{type_name} (the type of topic '{topic}') has no field "
                            f"'{'.'.join(ref.path)}'",
                            ref.at.line,
                            ref.at.col,
                        )
                        continue
                    problem = _kind_problem(kind, comparison, ref)
                    if problem:
                        sink.error(
                            f"'{ref.text}' is a {kind} field of {type_name}: {problem}",
                            ref.at.line,
                            ref.at.col,
                        )
            found += sink.items
        return found


def _comparisons(condition: Condition) -> list[Comparison]:
    if isinstance(condition, Comparison):
        return [condition]
    if isinstance(condition, Not):
        return _comparisons(condition.operand)
    return [c for operand in condition.operands for c in _comparisons(operand)]


def _field_pair_problem(
    comparison: Comparison, topic: str, types: Mapping[str, tuple[FieldLookup, str]]
) -> tuple[FieldRef, str] | None:
    """A field compared with another field of a kind it cannot be compared with, checked when
    the later of the two topics (`topic`) is known: (where to report it, the problem)."""
    left, right = comparison.left, comparison.right
    if not (isinstance(left, FieldRef) and isinstance(right, FieldRef)):
        return None
    if topic not in (left.topic, right.topic):
        return None
    if left.topic not in types or right.topic not in types:
        return None  # the other topic's type is not known yet: checked when it is
    kinds = []
    for ref in (left, right):
        ref_lookup, ref_type = types[ref.topic]
        kind = ref_lookup(ref.path)
        if kind not in ("number", "string", "bool"):
            return None  # a missing field, a message or an array: reported at the field
        kinds.append((kind, ref_type))
    (left_kind, left_type), (right_kind, right_type) = kinds
    at = left if left.topic == topic else right
    if {left_kind, right_kind} == {"number", "bool"}:
        return None  # Python compares a bool as 0/1, like a bool constant; allowed
    if left_kind != right_kind:
        return at, (
            f"'{left.text}' (a {left_kind} field of {left_type}) cannot be compared with "
            f"'{right.text}' (a {right_kind} field of {right_type})"
        )
    if left_kind in ("string", "bool") and comparison.op not in ("==", "!="):
        return at, (
            f"'{left.text}' and '{right.text}' are {left_kind} fields: a {left_kind} is "
            "compared with == or != only"
        )
    return None


def _kind_problem(kind: str, comparison: Comparison, ref: FieldRef) -> str:
    if kind in ("message", "array"):
        return "a condition compares plain values (name one of its fields)"
    other = comparison.right if comparison.left is ref else comparison.left
    if other is None:
        return "" if kind == "bool" else "a condition on its own must be a bool field"
    if isinstance(other, FieldRef):
        return ""  # checked when both types are known (_field_pair_problem)
    value = other.value
    expected = (
        "bool" if isinstance(value, bool) else "number" if isinstance(value, float) else "string"
    )
    if kind == "number" and expected == "bool":
        return ""  # a bool constant against a number: Python compares 0/1; allowed
    if expected != kind:
        return f"it cannot be compared with the {expected} {_shown(other)}"
    if kind in ("string", "bool") and comparison.op not in ("==", "!="):
        return f"a {kind} is compared with == or != only"
    return ""


def _shown(literal: Literal) -> str:
    value = literal.value
    if isinstance(value, bool):
        return "true" if value else "false"
    return f"{value:g}" if isinstance(value, float) else repr(value)


# -- contradictions -----------------------------------------------------------------------

Outcome = tuple[str, str]  # ("on" | "off", layer)


def _outcomes(rule: RuleDecl, hysteresis: bool = True) -> list[tuple[Outcome, Condition, bool]]:
    """(what happens, the condition under which it holds, whether that condition is
    negated). A 'while' rule with hysteresis keeps its layer while the relaxed condition
    holds (`x < 20 hysteresis 5`: until x >= 25), and its other outcome while the strict one
    does not (x >= 20): the widest each can be in force (without `hysteresis`: the strict
    condition both ways)."""
    if rule.mode == "activate":
        return [(("on", rule.layer.name), rule.condition, False)]
    if rule.mode == "deactivate":
        return [(("off", rule.layer.name), rule.condition, False)]
    otherwise = ("on", rule.otherwise.name) if rule.otherwise else ("off", rule.layer.name)
    holding = relaxed(rule.condition, rule.hysteresis) if hysteresis else rule.condition
    return [(("on", rule.layer.name), holding, False), (otherwise, rule.condition, True)]


def _contradiction(
    first: RuleDecl,
    second: RuleDecl,
    relations: Mapping[str, tuple[frozenset[str], frozenset[str]]],
    hysteresis: bool = True,
) -> str:
    for a, cond_a, neg_a in _outcomes(first, hysteresis):
        for b, cond_b, neg_b in _outcomes(second, hysteresis):
            why = _clashes(a, b, relations)
            if why and not _disjoint(cond_a, neg_a, cond_b, neg_b):
                return why
    return ""


def _through_hysteresis(first: RuleDecl, second: RuleDecl) -> str:
    """Why two contradicting rules hold together only through hysteresis ('' if not)."""
    margins = [rule for rule in (first, second) if rule.hysteresis and rule.mode == "while"]
    if not margins:
        return ""
    kept = " and ".join(
        f"{rule.name}'s hysteresis {rule.hysteresis:g} keeps it holding past its threshold"
        for rule in margins
    )
    return f" ({kept})"


def _clashes(
    a: Outcome, b: Outcome, relations: Mapping[str, tuple[frozenset[str], frozenset[str]]]
) -> str:
    (verb_a, layer_a), (verb_b, layer_b) = a, b
    if layer_a == layer_b:
        return "" if verb_a == verb_b else f"one activates {layer_a} while the other deactivates it"
    if verb_a == verb_b == "on":
        groups_a, excludes_a = relations.get(layer_a, (frozenset(), frozenset()))
        groups_b, excludes_b = relations.get(layer_b, (frozenset(), frozenset()))
        shared = groups_a & groups_b
        if shared:
            return (
                f"activate {layer_a} and {layer_b}, both of exclusive group {sorted(shared)[0]!r}"
            )
        if layer_b in excludes_a or layer_a in excludes_b:
            return f"activate {layer_a} and {layer_b}, which exclude each other"
    return ""


Interval = tuple[float, bool, float, bool]  # low, low inclusive, high, high inclusive


def _constraints(condition: Condition, negated: bool) -> dict[str, Interval] | None:
    """The condition as one interval per numeric field, if it is a conjunction of
    comparisons of fields with numbers (else None: nothing is known)."""
    if isinstance(condition, Not):
        return _constraints(condition.operand, not negated)
    if isinstance(condition, BoolOp):
        if (condition.op == "and") == negated:  # an 'or', or a negated 'and'
            return None
        merged: dict[str, Interval] = {}
        for operand in condition.operands:
            part = _constraints(operand, negated)
            if part is None:
                continue  # a conjunct we cannot read only weakens what we know: fine
            for key, interval in part.items():
                merged[key] = _intersect(merged[key], interval) if key in merged else interval
        return merged
    left, op, right = condition.left, condition.op, condition.right
    if isinstance(right, FieldRef) and isinstance(left, Literal):
        left, right = right, left
        op = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}.get(op, op)
    if not (isinstance(left, FieldRef) and isinstance(right, Literal)):
        return None
    if not isinstance(right.value, float) or isinstance(right.value, bool):
        return None  # strings and bools: not intervals
    if negated:
        op = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}[op]
    value, inf = right.value, float("inf")
    intervals = {
        "<": (-inf, False, value, False),
        "<=": (-inf, False, value, True),
        ">": (value, False, inf, False),
        ">=": (value, True, inf, False),
        "==": (value, True, value, True),
    }
    if op not in intervals:
        return None
    return {left.text: intervals[op]}


def _intersect(a: Interval, b: Interval) -> Interval:
    low = max((a[0], a[1]), (b[0], b[1]), key=lambda edge: (edge[0], not edge[1]))
    high = min((a[2], a[3]), (b[2], b[3]), key=lambda edge: (edge[0], edge[1]))
    return (low[0], low[1], high[0], high[1])


def _empty(interval: Interval) -> bool:
    low, low_in, high, high_in = interval
    return low > high or (low == high and not (low_in and high_in))


def _disjoint(a: Condition, neg_a: bool, b: Condition, neg_b: bool) -> bool:
    """True only when the two conditions provably cannot hold at once."""
    if a is b and neg_a != neg_b:
        return True
    first, second = _constraints(a, neg_a), _constraints(b, neg_b)
    if first is None or second is None:
        return False
    return any(_empty(_intersect(first[key], second[key])) for key in first.keys() & second.keys())
