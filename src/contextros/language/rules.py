"""Context rules: the `rule` declarations of layer files, parsed the same in every flavour.

A rule derives a context from the robot's own topics and from the ROS graph's state (a
node's lifecycle state, a node's parameter), one line in a layer file:

    rule GpsFix: Outdoor while gps/fix.status.status >= 0 for 0.15 s else Indoor
    rule Battery: LowBattery while battery.percentage < 20 for 2 s hysteresis 5
    rule Dock: activate Docked when dock/contact.data == true
    rule Degraded: SafeMode while lifecycle drivers/propeller != active
    rule Slow: Careful while param controller.max_speed < 0.5

A rule holds no code of the host language, so this grammar, its syntax tree and its
diagnostics are language-neutral: the Python and the C++ flavour's parsers hand the text
after `rule NAME:` to `parse_rule`. Evaluation lives in `contextros.rules` (ROS-free), the
subscriptions in `contextros.ros.rules`.

Grammar (EBNF; `TOPIC.FIELD` reads a field of the latest message on a topic, e.g.
`gps/fix.status.status`: a ROS name has no dots, so the first dot ends the topic):

    rule      = "rule" NAME ":" action ;
    action    = LAYER "while" condition [hold] [hysteresis] ["else" LAYER]
              | ("activate" | "deactivate") LAYER "when" condition [hold] ;
    hold      = "for" NUMBER ("s" | "ms") ;
    hysteresis = "hysteresis" NUMBER ;
    condition = conjunct { "or" conjunct } ;
    conjunct  = negation { "and" negation } ;
    negation  = "not" negation | "(" condition ")" | comparison ;
    comparison = operand [ ("<" | "<=" | ">" | ">=" | "==" | "!=") operand ] ;
    operand   = FIELD | NUMBER | STRING | "true" | "false" | graph ;
    graph     = "lifecycle" NODE | "param" NODE "." PARAMETER ;

`lifecycle NODE` is compared with `==`/`!=` against a lifecycle state, written bare
(`lifecycle drivers/propeller != active`, one of LIFECYCLE_STATES); `param NODE.PARAMETER`
reads a parameter's value like a field (the first dot ends the node's name; the rest, dots
included, is the parameter's: `param controller.gains.kp`).
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field, replace

from contextros.language.diagnostics import DiagnosticSink
from contextros.language.literals import string_literal
from contextros.language.positions import Position, Ref

COMPARISONS = ("<=", ">=", "==", "!=", "<", ">")
# How deep `not` and parentheses may nest in a condition (the parser recurses per level).
MAX_NESTING = 100
_KEYWORDS = frozenset(
    {"while", "when", "for", "else", "hysteresis", "and", "or", "not", "activate", "deactivate"}
)
# The states a lifecycle node reports (lifecycle_msgs/msg/State: the primary states, then
# the transitions between them), by their ids there.
LIFECYCLE_STATES = {
    1: "unconfigured",
    2: "inactive",
    3: "active",
    4: "finalized",
    10: "configuring",
    11: "cleaningup",
    12: "shuttingdown",
    13: "activating",
    14: "deactivating",
    15: "errorprocessing",
}
GRAPH_WORDS = ("lifecycle", "param")
_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_RULE_TOKEN = re.compile(
    rf"""(?P<ws>[ \t]+)
    |(?P<comment>\#.*)
    |(?P<field>~?/?{_NAME}(?:/{_NAME})*(?:\.{_NAME})+)
    |(?P<node>~?/{_NAME}(?:/{_NAME})*|{_NAME}(?:/{_NAME})+)
    |(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)
    |(?P<string>"(?:[^"\\]|\\.)*"|'(?:[^'\\]|\\.)*')
    |(?P<op><=|>=|==|!=|<|>|\(|\))
    |(?P<name>{_NAME})
    """,
    re.VERBOSE,
)


@dataclass(frozen=True)
class FieldRef:
    """`topic.a.b`: field `a.b` of the latest message on `topic` (relative to the namespace
    of the node running the rules)."""

    topic: str
    path: tuple[str, ...]
    at: Position

    @property
    def text(self) -> str:
        return f"{self.topic}.{'.'.join(self.path)}"


@dataclass(frozen=True)
class GraphRef:
    """`lifecycle NODE` (the node's lifecycle state, a string of LIFECYCLE_STATES) or
    `param NODE.PARAMETER` (the parameter's value): the ROS graph's state, read like a field.
    `node` is named as the rule names it (resolved in the manager's namespace, like a topic);
    `parameter` is '' for `lifecycle`."""

    kind: str  # "lifecycle" | "param"
    node: str
    parameter: str
    at: Position

    @property
    def text(self) -> str:
        """As written, normalised: the engine's name for this input."""
        if self.kind == "lifecycle":
            return f"lifecycle {self.node}"
        return f"param {self.node}.{self.parameter}"


Value = float | str | bool


@dataclass(frozen=True)
class Literal:
    value: Value
    at: Position


Operand = FieldRef | Literal | GraphRef


@dataclass(frozen=True)
class Comparison:
    """`left OP right`, or a lone operand (`op` empty: the field's truth value)."""

    left: Operand
    op: str
    right: Operand | None
    at: Position


@dataclass(frozen=True)
class Not:
    operand: Condition
    at: Position


@dataclass(frozen=True)
class BoolOp:
    op: str  # "and" | "or"
    operands: tuple[Condition, ...]
    at: Position


Condition = Comparison | Not | BoolOp


@dataclass
class RuleDecl:
    """One rule. `mode` is "while" (the layer follows the condition: active while it holds,
    deactivated, or `otherwise` activated, when it stops holding), "activate" or
    "deactivate" (done when the condition starts holding)."""

    name: str
    at: Position
    mode: str
    layer: Ref
    condition: Condition
    text: str  # the rule as written, after 'rule NAME:'
    hold: float = 0.0  # seconds the condition must keep its new value before acting
    hysteresis: float = 0.0  # how far past a threshold a 'while' condition must go back
    otherwise: Ref | None = None
    fields: list[FieldRef] = field(default_factory=list)  # topic fields
    graph: list[GraphRef] = field(default_factory=list)  # lifecycle states and parameters
    path: str = "<rules>"  # the file it was read from, for later diagnostics

    def targets(self) -> tuple[str, ...]:
        return (self.layer.name,) + ((self.otherwise.name,) if self.otherwise else ())

    def describe(self) -> str:
        return f"rule {self.name}: {self.text}"


@dataclass(frozen=True)
class _Tok:
    kind: str
    text: str
    col: int  # 1-based, in the file's line


class _RuleParser:
    def __init__(self, text: str, line: int, col: int, sink: DiagnosticSink) -> None:
        self.line = line
        self.sink = sink
        self.tokens: list[_Tok] = []
        self.end_col = col + len(text.rstrip())
        self.ok = self._tokenize(text, col)
        self.i = 0
        self.depth = 0
        self.fields: list[FieldRef] = []
        self.graph: list[GraphRef] = []

    def _tokenize(self, text: str, col: int) -> bool:
        pos = 0
        while pos < len(text):
            match = _RULE_TOKEN.match(text, pos)
            if match is None:
                self.sink.error(
                    f"unexpected character {text[pos]!r} in a rule", self.line, col + pos
                )
                return False
            kind = match.lastgroup or ""
            if kind == "comment":
                self.end_col = col + len(text[:pos].rstrip())
                break
            if kind != "ws":
                self.tokens.append(_Tok(kind, match.group(), col + pos))
            pos = match.end()
        return True

    # -- helpers ------------------------------------------------------------------------

    def peek(self) -> _Tok | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def at(self) -> Position:
        token = self.peek()
        return Position(self.line, token.col if token else self.end_col)

    def fail(self, expected: str) -> None:
        token = self.peek()
        found = f", found {token.text!r}" if token else ", found the end of the line"
        self.sink.error(f"expected {expected}{found}", self.line, self.at().col)
        raise _Stop

    def word(self, *words: str) -> str | None:
        token = self.peek()
        if token is not None and token.kind == "name" and token.text in words:
            self.i += 1
            return token.text
        return None

    def layer(self, what: str) -> Ref:
        token = self.peek()
        if token is None or token.kind != "name" or token.text in _KEYWORDS:
            self.fail(what)
        assert token is not None
        self.i += 1
        return Ref(token.text, Position(self.line, token.col))

    def number(self, what: str) -> float:
        token = self.peek()
        if token is None or token.kind != "number":
            self.fail(what)
        assert token is not None
        self.i += 1
        value = float(token.text)
        if not math.isfinite(value) or value < 0:
            self.sink.error(f"{what} must be a finite number >= 0", self.line, token.col)
            raise _Stop
        return value

    # -- grammar ------------------------------------------------------------------------

    def rule(self, name: Ref, text: str) -> RuleDecl:
        if not self.tokens:
            self.fail("a rule: 'LAYER while CONDITION' or 'activate|deactivate LAYER when ...'")
        mode = self.word("activate", "deactivate")
        layer = self.layer("the layer the rule switches")
        if mode is None:
            if self.word("while") is None:
                self.fail("'while' after the layer (or 'activate LAYER when ...')")
            mode = "while"
        elif self.word("when") is None:
            self.fail(f"'when' after '{mode} {layer.name}'")
        condition = self.condition()
        rule = RuleDecl(
            name.name,
            name.at,
            mode,
            layer,
            condition,
            text,
            fields=self.fields,
            graph=self.graph,
            path=self.sink.path,
        )
        if self.word("for") is not None:
            amount = self.number("a duration after 'for'")
            unit = self.word("s", "ms")
            if unit is None:
                self.fail("the unit of the duration, 's' or 'ms'")
            rule.hold = amount / 1000 if unit == "ms" else amount
        if self.word("hysteresis") is not None:
            if mode != "while":
                self.sink.error(
                    "'hysteresis' applies to 'while' rules (an 'activate'/'deactivate' rule "
                    "takes two rules with different thresholds)",
                    self.line,
                    self.tokens[self.i - 1].col,
                )
                raise _Stop
            rule.hysteresis = self.number("the hysteresis margin")
        if self.word("else") is not None:
            if mode != "while":
                self.sink.error(
                    "'else' applies to 'while' rules", self.line, self.tokens[self.i - 1].col
                )
                raise _Stop
            rule.otherwise = self.layer("the layer to activate when the condition fails")
            if rule.otherwise.name == layer.name:
                self.sink.error(
                    f"'else {layer.name}' names the rule's own layer",
                    self.line,
                    rule.otherwise.at.col,
                )
                raise _Stop
        if self.peek() is not None:
            self.fail("the end of the rule ('for', 'hysteresis' or 'else' may follow)")
        return rule

    def condition(self) -> Condition:
        start = self.at()
        operands = [self.conjunct()]
        while self.word("or") is not None:
            operands.append(self.conjunct())
        return operands[0] if len(operands) == 1 else BoolOp("or", tuple(operands), start)

    def conjunct(self) -> Condition:
        start = self.at()
        operands = [self.negation()]
        while self.word("and") is not None:
            operands.append(self.negation())
        return operands[0] if len(operands) == 1 else BoolOp("and", tuple(operands), start)

    def negation(self) -> Condition:
        start = self.at()
        token = self.peek()
        if token is None or (token.text != "(" and (token.kind, token.text) != ("name", "not")):
            return self.comparison()
        if self.depth >= MAX_NESTING:
            self.sink.error(
                f"the condition nests too deeply: more than {MAX_NESTING} levels of 'not' and "
                "parentheses",
                start.line,
                start.col,
            )
            raise _Stop
        self.depth += 1
        try:
            if self.word("not") is not None:
                return Not(self.negation(), start)
            self.i += 1  # "("
            inner = self.condition()
            token = self.peek()
            if token is None or token.text != ")":
                self.fail("')'")
            self.i += 1
            return inner
        finally:
            self.depth -= 1

    def comparison(self) -> Comparison:
        start = self.at()
        left = self.operand()
        token = self.peek()
        if token is not None and token.text in COMPARISONS:
            self.i += 1
            right = self.state(token) if _is_lifecycle(left) else self.operand()
            if isinstance(left, Literal) and isinstance(right, Literal):
                self.sink.error(
                    "a comparison of two constants: one side must be a field (TOPIC.FIELD)",
                    start.line,
                    start.col,
                )
                raise _Stop
            if _is_lifecycle(right) and not _is_lifecycle(left):
                self.sink.error(
                    "write the lifecycle state's side first: lifecycle NODE == STATE",
                    start.line,
                    start.col,
                )
                raise _Stop
            return Comparison(left, token.text, right, start)
        if _is_lifecycle(left):
            assert isinstance(left, GraphRef)
            self.sink.error(
                f"compare the lifecycle state with a state: {left.text} == active "
                f"(the states are {_STATE_LIST})",
                start.line,
                start.col,
            )
            raise _Stop
        if isinstance(left, Literal):
            self.sink.error(
                "a condition needs a field (TOPIC.FIELD, e.g. battery.percentage < 20), a "
                "parameter (param NODE.PARAMETER) or a lifecycle state (lifecycle NODE)",
                start.line,
                start.col,
            )
            raise _Stop
        return Comparison(left, "", None, start)

    def state(self, op: _Tok) -> Operand:
        """The other side of `lifecycle NODE ==`: a state, bare or quoted (or another
        node's lifecycle state)."""
        if op.text not in ("==", "!="):
            self.sink.error(
                "a lifecycle state is compared with == or != only (lifecycle NODE == active)",
                self.line,
                op.col,
            )
            raise _Stop
        token = self.peek()
        if token is not None and token.kind == "name" and token.text not in GRAPH_WORDS:
            self.i += 1
            value, at = token.text, Position(self.line, token.col)
        else:
            operand = self.operand()
            if _is_lifecycle(operand):
                return operand
            if not (isinstance(operand, Literal) and isinstance(operand.value, str)):
                self.sink.error(
                    f"a lifecycle state is compared with a state: one of {_STATE_LIST}",
                    operand.at.line,
                    operand.at.col,
                )
                raise _Stop
            value, at = operand.value, operand.at
        if value not in LIFECYCLE_STATES.values():
            close = difflib.get_close_matches(value, LIFECYCLE_STATES.values(), n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            self.sink.error(
                f"unknown lifecycle state {value!r}{hint}: the states are {_STATE_LIST}",
                at.line,
                at.col,
            )
            raise _Stop
        return Literal(value, at)

    def graph_ref(self, word: _Tok) -> GraphRef:
        """`lifecycle NODE` or `param NODE.PARAMETER` (`word` is the first word)."""
        self.i += 1
        at = Position(self.line, word.col)
        lifecycle = word.text == "lifecycle"
        example = (
            "lifecycle drivers/propeller != active"
            if lifecycle
            else ("param controller.max_speed < 0.5")
        )
        token = self.peek()
        if token is None or token.kind not in ("name", "node", "field") or token.text in _KEYWORDS:
            self.fail(f"the node after '{word.text}' (e.g. {example})")
        assert token is not None
        self.i += 1
        if token.text.startswith("~"):
            self.sink.error(
                f"{token.text!r}: a node is named by its namespace and name ('~' makes a topic "
                "private to the manager, not a node)",
                self.line,
                token.col,
            )
            raise _Stop
        if lifecycle:
            if token.kind == "field":
                self.sink.error(
                    f"{token.text!r} is not a node name: a node name has no '.' (e.g. {example})",
                    self.line,
                    token.col,
                )
                raise _Stop
            ref = GraphRef("lifecycle", token.text, "", at)
        else:
            if token.kind != "field":
                self.sink.error(
                    f"'param {token.text}' names no node: write param NODE.PARAMETER, the node "
                    f"whose parameter it is, then '.' and the parameter (e.g. {example})",
                    self.line,
                    token.col,
                )
                raise _Stop
            node, _, parameter = token.text.partition(".")
            ref = GraphRef("param", node, parameter, at)
        self.graph.append(ref)
        return ref

    def operand(self) -> Operand:
        token = self.peek()
        if token is None:
            self.fail("a field (TOPIC.FIELD) or a constant")
        assert token is not None
        at = Position(self.line, token.col)
        if token.kind == "field":
            self.i += 1
            topic, *path = token.text.split(".")
            ref = FieldRef(topic, tuple(path), at)
            self.fields.append(ref)
            return ref
        if token.kind == "number":
            self.i += 1
            value = float(token.text)
            if not math.isfinite(value):
                self.sink.error(f"{token.text} is not a finite number", at.line, at.col)
                raise _Stop
            return Literal(value, at)
        if token.kind == "string":
            self.i += 1
            text = string_literal(token.text, at.line, at.col, self.sink)
            if text is None:
                raise _Stop
            return Literal(text, at)
        if token.kind == "name" and token.text in GRAPH_WORDS:
            return self.graph_ref(token)
        if token.kind == "name" and token.text in ("true", "false"):
            self.i += 1
            return Literal(token.text == "true", at)
        if token.kind == "name":
            self.sink.error(
                f"{token.text!r} is not a field: write TOPIC.FIELD (e.g. "
                f"{token.text}.data for a std_msgs value on topic '{token.text}')",
                at.line,
                at.col,
            )
            raise _Stop
        self.fail("a field (TOPIC.FIELD) or a constant")
        raise AssertionError("unreachable")


def _is_lifecycle(operand: Operand | None) -> bool:
    return isinstance(operand, GraphRef) and operand.kind == "lifecycle"


_STATE_LIST = (
    ", ".join(list(LIFECYCLE_STATES.values())[:4])
    + "; during a transition "
    + ", ".join(list(LIFECYCLE_STATES.values())[4:])
)


class _Stop(Exception):
    """The rule has an error (already reported)."""


def parse_rule(name: Ref, text: str, line: int, col: int, sink: DiagnosticSink) -> RuleDecl | None:
    """The rule `text` (what follows `rule NAME:`, starting at `line`:`col` of the file);
    errors go to `sink` with their position, and give None."""
    parser = _RuleParser(text, line, col, sink)
    if not parser.ok:
        return None
    try:
        return parser.rule(name, text[: max(0, parser.end_col - col)].strip())
    except _Stop:
        return None


# Which way hysteresis moves a threshold against a number so that the condition holds
# longer: `x < 20 hysteresis 5` holds until x >= 25 (under `not`, the other way).
_RELAX = {"<": 1.0, "<=": 1.0, ">": -1.0, ">=": -1.0}
_MIRRORED = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}


def relaxed(condition: Condition, margin: float, sign: float = 1.0) -> Condition:
    """`condition` as a 'while' rule with `hysteresis margin` evaluates it once it holds:
    each threshold against a number moved by `margin` the way that keeps it true (`x < 20`
    becomes `x < 25`; under `not`, the other way; `==` and `!=` stay). The engine runs
    it, and the contradiction check reads it, so both mean the same condition."""
    if not margin:
        return condition
    if isinstance(condition, Not):
        return Not(relaxed(condition.operand, margin, -sign), condition.at)
    if isinstance(condition, BoolOp):
        operands = tuple(relaxed(operand, margin, sign) for operand in condition.operands)
        return BoolOp(condition.op, operands, condition.at)
    left, op, right = condition.left, condition.op, condition.right
    if isinstance(right, Literal) and isinstance(right.value, float):
        moved = right.value + _RELAX.get(op, 0.0) * sign * margin
        return replace(condition, right=Literal(moved, right.at))
    if isinstance(left, Literal) and isinstance(left.value, float):
        moved = left.value + _RELAX.get(_MIRRORED.get(op, op), 0.0) * sign * margin
        return replace(condition, left=Literal(moved, left.at))
    return condition


def condition_text(condition: Condition) -> str:
    """The condition written back (normalised spacing), for reasons and logs."""
    if isinstance(condition, Not):
        return f"not {_grouped(condition.operand)}"
    if isinstance(condition, BoolOp):
        return f" {condition.op} ".join(_grouped(c) for c in condition.operands)
    left = _operand_text(condition.left)
    if condition.right is None:
        return left
    right = condition.right
    if _is_lifecycle(condition.left) and isinstance(right, Literal):
        return f"{left} {condition.op} {right.value}"  # a state, bare as written
    return f"{left} {condition.op} {_operand_text(right)}"


def _grouped(condition: Condition) -> str:
    text = condition_text(condition)
    return f"({text})" if isinstance(condition, BoolOp) else text


def _operand_text(operand: Operand) -> str:
    if isinstance(operand, FieldRef | GraphRef):
        return operand.text
    if isinstance(operand.value, bool):
        return "true" if operand.value else "false"
    if isinstance(operand.value, float):
        return f"{operand.value:g}"
    return repr(operand.value)
