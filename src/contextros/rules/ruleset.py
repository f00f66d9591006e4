"""A set of context rules, from layer files or the Python API, with its static checks."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from contextros.language.diagnostics import (
    Diagnostic,
    DiagnosticSink,
    LayerSyntaxError,
    Severity,
)
from contextros.language.flavours import parse_files
from contextros.language.positions import Position, Ref
from contextros.language.rules import (
    Comparison,
    Condition,
    FieldRef,
    GraphRef,
    Literal,
    Not,
    RuleDecl,
    parse_rule,
)
from contextros.language.syntax import LayerFile
from contextros.language.topics import TopicDecl
from contextros.rules.contradictions import Relations, contradiction

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
        """The rules of layer files (either flavour), checked together (`check`, with
        `message_types` the declared topics' fields too); LayerSyntaxError lists every
        error. The rest of each file (layers, methods, bindings) is the checker's:
        `contextros.language.checker.check_files` runs every check, as the manager does."""
        parsed, errors = parse_files(paths, language)
        result = cls.from_parsed(parsed)
        errors += [d for d in result.check(message_types=message_types) if d.is_error]
        if errors:
            raise LayerSyntaxError(errors)
        return result

    @classmethod
    def from_parsed(cls, parsed: Iterable[tuple[str, str, LayerFile]]) -> RuleSet:
        """The rules and topic declarations of parsed layer files ((name, source, tree)
        each), merged in their order."""
        rules: list[RuleDecl] = []
        topics: list[TopicDecl] = []
        sources: dict[str, str] = {}
        for name, source, layer_file in parsed:
            rules += layer_file.rules
            topics += layer_file.topics
            sources[name] = source
        return cls(rules, sources, topics)

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

    def _diagnostic(
        self, item: RuleDecl | TopicDecl, severity: Severity, message: str, at: Position
    ) -> Diagnostic:
        """One diagnostic at `at` of the file `item` came from, its line quoted."""
        sink = self.sink_for(item)
        sink.add(severity, message, at.line, at.col)
        return sink.items[0]

    # -- static checks ------------------------------------------------------------------

    def topics(self) -> tuple[str, ...]:
        """Every topic the rules read, in order of first mention."""
        return tuple(dict.fromkeys(ref.topic for rule in self.rules for ref in rule.fields))

    def check(
        self, relations: Relations | None = None, message_types: MessageTypes | None = None
    ) -> list[Diagnostic]:
        """Duplicate names, topic declarations, and pairs of rules that may hold at once
        while switching to contradicting targets (the same layer on and off, two layers of
        one group, or two that exclude each other). `relations` maps a layer to (its
        groups, what it excludes); without it only the same-layer contradiction is known.
        With `message_types`, the fields of declared topics too (`check_declared_fields`)."""
        found: list[Diagnostic] = []
        seen: dict[str, RuleDecl] = {}
        for rule in self.rules:
            first = seen.get(rule.name)
            if first is not None:
                already = f"rule {rule.name!r} is already declared at {self.where(first)}"
                found.append(self._diagnostic(rule, Severity.ERROR, already, rule.at))
            seen.setdefault(rule.name, rule)
        found += self._check_declarations()
        for index, first in enumerate(self.rules):
            for second in self.rules[index + 1 :]:
                clash = contradiction(first, second, relations or {})
                if clash:
                    warning = (
                        f"rules {first.name} ({self.where(first)}) and {second.name} {clash}: "
                        f"when both fire together, {first.name} (declared first) wins and the "
                        "other is logged as overridden; make their conditions exclusive"
                    )
                    found.append(self._diagnostic(second, Severity.WARNING, warning, second.at))
        if message_types is not None:
            found += self.check_declared_fields(message_types)
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
                missing = (
                    f"the declared type of topic '{declaration.topic}' does not exist: {error}"
                )
                found.append(
                    self._diagnostic(declaration, Severity.ERROR, missing, declaration.type_at)
                )
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

    def type_mismatch(
        self, topic: str, resolved: str, type_name: str, *, published: bool = True
    ) -> Diagnostic | None:
        """The error for `topic` seen on the graph (as `resolved`) with `type_name` while
        declared with another type, at the declaration's type; None when they agree or it is
        not declared. Not `published`: only subscribers give the graph that type."""
        declaration = self.topic_types.get(topic)
        if declaration is None or declaration.type_name == type_name:
            return None
        users = [rule.name for rule in self.rules if any(r.topic == topic for r in rule.fields)]
        seen = (
            f"is published as {type_name}"
            if published
            else f"has type {type_name} on the ROS graph, from its subscribers (no node "
            "publishes it)"
        )
        mismatch = (
            f"topic {resolved} {seen}, but topic '{topic}' is declared "
            f"as {declaration.type_name}: the rules reading it ({', '.join(users)}) stay off"
        )
        return self._diagnostic(declaration, Severity.ERROR, mismatch, declaration.type_at)

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
            for comparison in comparisons(rule.condition):
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


def comparisons(condition: Condition) -> list[Comparison]:
    """Every comparison in `condition`, in order."""
    if isinstance(condition, Comparison):
        return [condition]
    if isinstance(condition, Not):
        return comparisons(condition.operand)
    return [c for operand in condition.operands for c in comparisons(operand)]


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
    if isinstance(other, FieldRef | GraphRef):
        return ""  # checked when both types are known (_field_pair_problem), or at run time
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
