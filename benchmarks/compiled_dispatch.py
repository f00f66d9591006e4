"""A compiled layer file's dispatch, side by side with a plain call (target: one active
layer <= 2x plain).

The layer file below is compiled and loaded with `contextros.load`. Every function
computes ``x + 1``. Cases: the plain function from the file's header; the dispatch
function with no active layer (runs the base); with one active layer that does not
proceed; with one active layer that proceeds to the base (two calls' worth of work); a
method of a class refined by the file (its layer functions live in another module than
the class, so the core goes through a one-line trampoline); and, for reference, the
paper's Listing 2 dispatch written by hand (`if layer == ...: elif ...`).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from benchmarks.timing import ns_per_call
from contextros import set_active
from contextros.language import load

TARGET = 2.0

LAYERS = '''\
from benchmarks.compiled_dispatch import Counter


def plain(x):
    return x + 1


ACTIVE = ["BenchFast"]


def step_Fast_by_hand(x):
    return x + 1


def step_Slow_by_hand(x):
    return x + 1


def listing2_step(x):
    """The paper's Listing 2: a dispatcher testing the active layer on every call."""
    layer = ACTIVE[0]
    if layer == "BenchFast":
        return step_Fast_by_hand(x)
    elif layer == "BenchSlow":
        return step_Slow_by_hand(x)


group bench_mode: BenchFast, BenchSlow

base:
    def step(x):
        return x + 1

layer BenchFast:
    def step(x):
        return x + 1

    def Counter.step(self, x):
        return x + 1

layer BenchSlow:
    def step(x):
        return proceed(x)
'''


PLAIN_FUNCTION = "plain function call"
PLAIN_METHOD = "plain method call"

# (case, active layers, statement, the plain case it is compared with)
CASES = [
    ("compiled dispatch, no active layer (base)", [], "m.step(1)", PLAIN_FUNCTION),
    ("compiled dispatch, one active layer", ["BenchFast"], "m.step(1)", PLAIN_FUNCTION),
    ("compiled dispatch, one layer that proceeds", ["BenchSlow"], "m.step(1)", PLAIN_FUNCTION),
    (
        "hand-written Listing 2 if/elif dispatch",
        ["BenchFast"],
        "m.listing2_step(1)",
        PLAIN_FUNCTION,
    ),
    ("method of a class, one active layer (trampoline)", ["BenchFast"], "c.step(1)", PLAIN_METHOD),
]


def run() -> list[dict[str, Any]]:
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "bench_compiled_dispatch.layers"
        path.write_text(LAYERS)
        module = load(path)
    env = {"m": module, "c": module.Counter(), "plain_counter": _PlainCounter()}
    plains = {PLAIN_FUNCTION: ("m.plain(1)", env), PLAIN_METHOD: ("plain_counter.step(1)", env)}
    measured: dict[str, float] = {}
    for case, layers, statement, baseline in CASES:
        set_active(layers)
        timed = ns_per_call({baseline: plains[baseline], case: (statement, env)})
        measured[case] = timed[case]
        measured[baseline] = min(measured.get(baseline, float("inf")), timed[baseline])
    set_active([])
    rows: list[dict[str, Any]] = [
        {"case": name, "ns_per_call": measured[name], "ratio_to_plain": 1.0} for name in plains
    ]
    for case, _, _, baseline in CASES:
        rows.append(
            {
                "case": case,
                "ns_per_call": measured[case],
                "ratio_to_plain": measured[case] / measured[baseline],
                "compared_with": baseline,
                "target": TARGET if case == "compiled dispatch, one active layer" else None,
            }
        )
    return rows


class _PlainCounter:
    def step(self, x: int) -> int:
        return x + 1


class Counter:
    """Refined by the layer file from another module: the trampoline case."""

    def step(self, x: int) -> int:
        return x + 1


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = ["| case | ns/call | x plain | compared with | target |", "|---|---:|---:|---|---|"]
    for row in rows:
        target = row.get("target")
        verdict = ""
        if target is not None:
            verdict = f"<= {target}x: {'met' if row['ratio_to_plain'] <= target else 'MISSED'}"
        lines.append(
            f"| {row['case']} | {row['ns_per_call']:.1f} | {row['ratio_to_plain']:.2f} | "
            f"{row.get('compared_with', '')} | {verdict} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(run()))
