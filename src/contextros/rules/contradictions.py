"""Whether two rules contradict: they may hold at the same time while one activates a layer
the other deactivates, or both activate two members of one exclusive group, or two layers
that exclude each other (docs/rules.md, "Contradicting rules"). Conservative: a pair is
reported unless comparisons of the same field with numbers prove the conditions exclusive
(as intervals). A 'while' rule with hysteresis is read as the engine runs it: holding on
its relaxed condition, its other outcome on the strict one."""

from __future__ import annotations

from collections.abc import Mapping

from contextros.language.rules import (
    LIFECYCLE_STATES,
    BoolOp,
    Condition,
    FieldRef,
    GraphRef,
    Literal,
    Not,
    RuleDecl,
    relaxed,
)

# layer -> (its groups, what it excludes)
Relations = Mapping[str, tuple[frozenset[str], frozenset[str]]]
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
    relations: Relations,
    hysteresis: bool = True,
) -> str:
    for a, cond_a, neg_a in _outcomes(first, hysteresis):
        for b, cond_b, neg_b in _outcomes(second, hysteresis):
            why = _clashes(a, b, relations)
            if why and not _disjoint(cond_a, neg_a, cond_b, neg_b):
                return why
    return ""


def contradiction(first: RuleDecl, second: RuleDecl, relations: Relations) -> str:
    """How two rules contradict, '' if they cannot: 'may hold at the same time and <what
    clashes>', saying when they hold together only through hysteresis."""
    clash = _contradiction(first, second, relations)
    if not clash:
        return ""
    only_relaxed = not _contradiction(first, second, relations, hysteresis=False)
    through = _through_hysteresis(first, second) if only_relaxed else ""
    return f"may hold at the same time{through} and {clash}"


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


def _clashes(a: Outcome, b: Outcome, relations: Relations) -> str:
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
# What a conjunction allows of one value: an interval of a number (a field, a parameter),
# or the set of states a lifecycle state may be in.
Allowed = Interval | frozenset[str]
_STATES = frozenset(LIFECYCLE_STATES.values())


def _constraints(condition: Condition, negated: bool) -> dict[str, Allowed] | None:
    """The condition as what it allows of each value, if it is a conjunction of comparisons
    of fields or parameters with numbers and of lifecycle states with states (else None:
    nothing is known)."""
    if isinstance(condition, Not):
        return _constraints(condition.operand, not negated)
    if isinstance(condition, BoolOp):
        if (condition.op == "and") == negated:  # an 'or', or a negated 'and'
            return None
        merged: dict[str, Allowed] = {}
        for operand in condition.operands:
            part = _constraints(operand, negated)
            if part is None:
                continue  # a conjunct we cannot read only weakens what we know: fine
            for key, interval in part.items():
                merged[key] = _intersect(merged[key], interval) if key in merged else interval
        return merged
    left, op, right = condition.left, condition.op, condition.right
    if isinstance(right, FieldRef | GraphRef) and isinstance(left, Literal):
        left, right = right, left
        op = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}.get(op, op)
    if not (isinstance(left, FieldRef | GraphRef) and isinstance(right, Literal)):
        return None
    if isinstance(left, GraphRef) and left.kind == "lifecycle":
        equal = (op == "==") != negated
        state = frozenset({str(right.value)})
        return {left.text: state if equal else _STATES - state}
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


def _intersect(a: Allowed, b: Allowed) -> Allowed:
    if isinstance(a, frozenset) or isinstance(b, frozenset):
        # (a value is a lifecycle state or a number, never both)
        assert isinstance(a, frozenset) and isinstance(b, frozenset)
        return a & b
    low = max((a[0], a[1]), (b[0], b[1]), key=lambda edge: (edge[0], not edge[1]))
    high = min((a[2], a[3]), (b[2], b[3]), key=lambda edge: (edge[0], edge[1]))
    return (low[0], low[1], high[0], high[1])


def _empty(allowed: Allowed) -> bool:
    if isinstance(allowed, frozenset):
        return not allowed
    low, low_in, high, high_in = allowed
    return low > high or (low == high and not (low_in and high_in))


def _disjoint(a: Condition, neg_a: bool, b: Condition, neg_b: bool) -> bool:
    """True only when the two conditions provably cannot hold at once."""
    if a is b and neg_a != neg_b:
        return True
    first, second = _constraints(a, neg_a), _constraints(b, neg_b)
    if first is None or second is None:
        return False
    return any(_empty(_intersect(first[key], second[key])) for key in first.keys() & second.keys())
