"""The PNG timeline of a rule replay: each signal a rule reads with its thresholds (and where
hysteresis moves them), the hold times that ended in a firing, and the active layers."""

from __future__ import annotations

import os
from collections.abc import Iterator

from contextros.language.rules import (
    BoolOp,
    Comparison,
    Condition,
    FieldRef,
    GraphRef,
    Literal,
    Not,
    relaxed,
)
from contextros.rules.replay import ReplayResult
from contextros.rules.ruleset import RuleSet


def thresholds(rules: RuleSet) -> dict[str, list[tuple[str, float, float]]]:
    """Per field: (rule, threshold, threshold once the condition holds) of each comparison
    of the field against a number (the engine's own `relaxed` condition gives the second)."""
    found: dict[str, list[tuple[str, float, float]]] = {}
    for rule in rules.rules:
        margin = rule.hysteresis if rule.mode == "while" else 0.0
        held = relaxed(rule.condition, margin)
        for strict, loose in zip(_comparisons(rule.condition), _comparisons(held), strict=True):
            limit, moved = _limit(strict), _limit(loose)
            if limit is not None and moved is not None:
                found.setdefault(limit[0], []).append((rule.name, limit[1], moved[1]))
    return found


def _limit(comparison: Comparison) -> tuple[str, float] | None:
    """(field, number) of a comparison of a field against a number."""
    left, right = comparison.left, comparison.right
    if isinstance(left, FieldRef | GraphRef) and isinstance(right, Literal):
        field, value = left, right.value
    elif isinstance(right, FieldRef | GraphRef) and isinstance(left, Literal):
        field, value = right, left.value
    else:
        return None
    if isinstance(value, bool) or not isinstance(value, float | int):
        return None
    return field.text, float(value)


def _comparisons(condition: Condition) -> Iterator[Comparison]:
    if isinstance(condition, Not):
        yield from _comparisons(condition.operand)
    elif isinstance(condition, BoolOp):
        for operand in condition.operands:
            yield from _comparisons(operand)
    elif condition.right is not None:
        yield condition


def write_timeline(
    result: ReplayResult, rules: RuleSet, start: float, end: float, path: str | os.PathLike[str]
) -> None:
    """Write the plot to `path` (PNG); times in seconds since `start`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    signals = sorted(result.signals)
    limits = thresholds(rules)
    layers = sorted({name for switch in result.switches for name in switch.active})
    rows = len(signals) + 1
    figure, axes = plt.subplots(
        rows, 1, sharex=True, figsize=(10, 2.2 * rows + 0.6), squeeze=False, layout="constrained"
    )
    for axis, name in zip(axes[:, 0], signals, strict=False):
        times = [t - start for t, _ in result.signals[name]]
        axis.step(times, [v for _, v in result.signals[name]], where="post", color="tab:blue")
        for rule, threshold, held in limits.get(name, []):
            axis.axhline(threshold, color="tab:red", linestyle="--", label=f"{rule} threshold")
            if held != threshold:
                axis.axhline(
                    held, color="tab:orange", linestyle=":", label=f"{rule} with hysteresis"
                )
        for rule, begin, finish in result.holds:
            read = [ref.text for r in rules.rules if r.name == rule for ref in r.fields]
            read += [ref.text for r in rules.rules if r.name == rule for ref in r.graph]
            if name in read:
                axis.axvspan(begin - start, finish - start, color="tab:green", alpha=0.2)
        axis.set_ylabel(name, fontsize=8)
        axis.legend(loc="upper right", fontsize=7)
    layer_axis = axes[-1, 0]
    for row, layer in enumerate(layers):
        spans = _spans(result, layer, end)
        layer_axis.broken_barh(
            [(a - start, b - a) for a, b in spans], (row - 0.4, 0.8), color=f"C{row % 10}"
        )
    for switch in result.switches:
        for axis in axes[:, 0]:
            axis.axvline(switch.time - start, color="grey", linewidth=0.6)
        label = switch.requester.removeprefix("rule ")
        layer_axis.annotate(
            label, (switch.time - start, len(layers) - 0.4), fontsize=7, rotation=90, va="bottom"
        )
    layer_axis.set_yticks(range(len(layers)), layers)
    layer_axis.set_ylim(-0.6, len(layers) + 1.4)
    layer_axis.set_xlim(0, max(end - start, 1e-3))
    layer_axis.set_xlabel("seconds since the recording began (grey: switches; green: hold times)")
    figure.suptitle("contextros rules replay")
    figure.savefig(path, dpi=100)
    plt.close(figure)


def _spans(result: ReplayResult, layer: str, end: float) -> list[tuple[float, float]]:
    spans, since = [], None
    for switch in result.switches:
        if layer in switch.active and since is None:
            since = switch.time
        elif layer not in switch.active and since is not None:
            spans.append((since, switch.time))
            since = None
    if since is not None:
        spans.append((since, end))
    return spans
