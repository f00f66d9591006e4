"""Dispatch cost of the COP core, side by side with a plain call and with ContextPy3.

Same workload everywhere: a method computing ``x + 1`` (partials add their own ``+ 1``).
Cases: no active layer; one active partial that does not proceed; one that proceeds to the
base; three stacked partials that proceed; one that proceeds behind a guard that holds (the
guard is a call of its own, and only guarded chains pay for it). Then the price of the newer
features for a class that does not use them: the same calls while another class has a layer
active for one of its objects (per-object activation puts only that class's methods on a
per-receiver path), and that per-receiver path itself. Scoped and per-object calls and a
guarded partial have a target of 3x a plain call, a proceeding partial 2x (issues 18, 26);
the last row, for reference, is the same proceeding chain behind one more plain function
frame, with no look-up at all: the floor of a dispatcher with a Python frame of its own. The
C dispatcher (`contextros.core.DISPATCHER == "c"`) runs the head it expects in its own frame,
so those calls go below it; `CONTEXTROS_PURE_PYTHON=1` measures the pure-Python one.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from benchmarks.timing import ns_per_call
from contextros import (
    Layer,
    activate_for,
    activated,
    layered,
    proceed,
    reset_for,
    set_active,
)

TARGETS = {
    "no active layer": 1.2,
    "one partial, no proceed": 1.2,
    "one partial, proceeds": 2.0,
    "three partials, proceed": None,
}
SCOPED = "one partial, proceeds, scoped (with activated)"
# The floor of any dispatcher in Python that finds its chain per call: the same chain behind
# one more plain Python frame, with no look-up at all (hand-written, for reference).
FLOOR = "reference: one partial, proceeds, behind one more plain frame"
SLOW_PATH_TARGET = 3.0  # scoped and per-object calls, a guarded partial (issues 18, 26)
GUARDED = "one guarded partial (guard true), proceeds"  # what a guard costs (issue 18)
# A class that does not use per-object activation, while another class does.
UNAFFECTED = {
    "no active layer, another class has per-object layers": 1.2,
    "one partial, proceeds, another class has per-object layers": 2.0,
}
PER_OBJECT = "one partial, proceeds, per-object (activate_for)"

L1, L2, L3 = Layer("BenchL1"), Layer("BenchL2"), Layer("BenchL3")


class Plain:
    def step(self, x: int) -> int:
        return x + 1


class Layered:
    @layered
    def step(self, x: int) -> int:
        return x + 1

    @step.partial(L1)
    def step(self, x: int) -> int:
        return proceed(self, x) + 1

    @step.partial(L2)
    def step(self, x: int) -> int:
        return proceed(self, x) + 1

    @step.partial(L3)
    def step(self, x: int) -> int:
        return proceed(self, x) + 1


class Elsewhere:
    """Another class, whose objects get layers of their own."""

    @layered
    def step(self, x: int) -> int:
        return x + 1

    @step.partial(L1)
    def step(self, x: int) -> int:
        return proceed(self, x) + 1


class Guarded:
    @layered
    def step(self, x: int) -> int:
        return x + 1

    @step.partial(L1, when=lambda self, x: x > 0)
    def step(self, x: int) -> int:
        return proceed(self, x) + 1


def _floor_base(self: object, x: int) -> int:
    return x + 1


def _floor_partial(self: object, x: int) -> int:
    return _floor_base(self, x) + 1


class Floor:
    def step(self, x: int) -> int:
        return _floor_partial(self, x)


class NoProceed:
    @layered
    def step(self, x: int) -> int:
        return x + 1

    @step.partial(L1)
    def step(self, x: int) -> int:
        return x + 2


def _contextros_cases() -> dict[str, float]:
    plain, layered_obj, no_proceed = Plain(), Layered(), NoProceed()
    results: dict[str, float] = {}
    for case, layers, obj in [
        ("no active layer", [], layered_obj),
        ("one partial, no proceed", [L1], no_proceed),
        ("one partial, proceeds", [L1], layered_obj),
        ("three partials, proceed", [L1, L2, L3], layered_obj),
        (GUARDED, [L1], Guarded()),
    ]:
        set_active(layers)
        timed = ns_per_call({"plain": ("o.step(1)", {"o": plain}), case: ("o.step(1)", {"o": obj})})
        results[case] = timed[case]
        results.setdefault("plain", timed["plain"])
        results["plain"] = min(results["plain"], timed["plain"])
    set_active([])
    with activated(L1):  # the context-variable path, as in a `with` block
        timed = ns_per_call(
            {
                "plain": ("o.step(1)", {"o": plain}),
                SCOPED: ("o.step(1)", {"o": layered_obj}),
                FLOOR: ("o.step(1)", {"o": Floor()}),
            }
        )
    results[SCOPED] = timed[SCOPED]
    results[FLOOR] = timed[FLOOR]
    results["plain"] = min(results["plain"], timed["plain"])
    elsewhere = Elsewhere()
    activate_for(elsewhere, L1)
    for case, layers in zip(UNAFFECTED, [[], [L1]], strict=True):
        set_active(layers)
        timed = ns_per_call(
            {"plain": ("o.step(1)", {"o": plain}), case: ("o.step(1)", {"o": layered_obj})}
        )
        results[case] = timed[case]
        results["plain"] = min(results["plain"], timed["plain"])
    set_active([])
    timed = ns_per_call(
        {"plain": ("o.step(1)", {"o": plain}), PER_OBJECT: ("o.step(1)", {"o": elsewhere})}
    )
    results[PER_OBJECT] = timed[PER_OBJECT]
    results["plain"] = min(results["plain"], timed["plain"])
    reset_for(elsewhere)
    return results


def _contextpy3_cases() -> dict[str, float] | None:
    try:
        import contextpy3 as cp
    except ImportError:
        return None
    c1, c2, c3 = cp.Layer("C1"), cp.Layer("C2"), cp.Layer("C3")

    class CpLayered:
        @cp.base
        def step(self, x: int) -> int:
            return x + 1

        @cp.around(c1)
        def step(self, x: int) -> int:  # noqa: F811 (ContextPy3 redefines by name)
            return cp.proceed(x) + 1

        @cp.around(c2)
        def step(self, x: int) -> int:  # noqa: F811 (ContextPy3 redefines by name)
            return cp.proceed(x) + 1

        @cp.around(c3)
        def step(self, x: int) -> int:  # noqa: F811 (ContextPy3 redefines by name)
            return cp.proceed(x) + 1

    class CpNoProceed:
        @cp.base
        def step(self, x: int) -> int:
            return x + 1

        @cp.around(c1)
        def step(self, x: int) -> int:  # noqa: F811 (ContextPy3 redefines by name)
            return x + 2

    results: dict[str, float] = {}
    obj, no_proceed = CpLayered(), CpNoProceed()
    for case, layers, target in [
        ("no active layer", [], obj),
        ("one partial, no proceed", [c1], no_proceed),
        ("one partial, proceeds", [c1], obj),
        ("three partials, proceed", [c1, c2, c3], obj),
    ]:
        for layer in layers:
            cp.global_activate_layer(layer)
        results[case] = ns_per_call({case: ("o.step(1)", {"o": target})}, number=20_000)[case]
        for layer in layers:
            cp.global_deactivate_layer(layer)
    with cp.active_layer(c1):
        results[SCOPED] = ns_per_call({SCOPED: ("o.step(1)", {"o": obj})}, number=20_000)[SCOPED]
    return results


def run() -> list[dict[str, Any]]:
    ours = _contextros_cases()
    theirs = _contextpy3_cases()
    plain = ours["plain"]
    rows: list[dict[str, Any]] = [{"case": "plain method", "ns": plain, "ratio": 1.0}]
    cases = [
        *TARGETS.items(),
        (GUARDED, SLOW_PATH_TARGET),
        (SCOPED, SLOW_PATH_TARGET),
        *UNAFFECTED.items(),
        (PER_OBJECT, SLOW_PATH_TARGET),
        (FLOOR, None),
    ]
    for case, target in cases:
        row: dict[str, Any] = {
            "case": case,
            "ns": ours[case],
            "ratio": ours[case] / plain,
            "target": target,
        }
        if theirs is not None and case in theirs:
            row["contextpy3_ns"] = theirs[case]
            row["speedup_vs_contextpy3"] = theirs[case] / ours[case]
        rows.append(row)
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| case | ContextROS ns/call | x plain | target | ContextPy3 ns/call "
        "| ContextROS faster by |",
        "|---|---:|---:|---|---:|---:|",
    ]
    for row in rows:
        target = row.get("target")
        verdict = ""
        if target is not None:
            verdict = f"<= {target}x: {'met' if row['ratio'] <= target else 'MISSED'}"
        cp_ns = f"{row['contextpy3_ns']:.0f}" if "contextpy3_ns" in row else ""
        speed = row.get("speedup_vs_contextpy3")
        speed_text = f"{speed:.0f}x" if speed else ""
        if speed and row["case"] in TARGETS:
            speed_text += f" ({'met' if speed >= 50 else 'MISSED'} >= 50x)"
        lines.append(
            f"| {row['case']} | {row['ns']:.1f} | {row['ratio']:.2f} | {verdict} | "
            f"{cp_ns} | {speed_text} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(run()))


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """ns per call of each case, ContextROS next to ContextPy3 (log scale: they differ ~100x)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = [row["case"] for row in rows]
    positions = range(len(cases))
    series = [("ContextROS", [row["ns"] for row in rows], 0.2)]
    if any("contextpy3_ns" in row for row in rows):
        series.append(("ContextPy3", [row.get("contextpy3_ns", math.nan) for row in rows], -0.2))
    figure, axes = plt.subplots(figsize=(8, 0.6 * len(cases) + 1.5))
    for label, values, shift in series:
        bars = axes.barh([p + shift for p in positions], values, 0.4, label=label)
        texts = ["" if math.isnan(v) else f"{v:.0f}" for v in values]
        axes.bar_label(bars, labels=texts, fontsize=7, padding=2)
    largest = max(v for _, values, _ in series for v in values if not math.isnan(v))
    axes.set_xscale("log")
    axes.set_xlim(right=largest * 3)  # room for the labels
    axes.set_yticks(list(positions), cases)
    axes.invert_yaxis()
    axes.set_xlabel("ns per call (fastest round, loop overhead removed)")
    axes.set_title("Dispatch cost per call")
    axes.legend(fontsize=8, loc="lower right")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
