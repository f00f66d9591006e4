"""Side-by-side micro-timing: every case measured in the same interleaved rounds.

The machines are shared and noisy, so cases are interleaved round by round and each
keeps its fastest round; the empty loop's cost is subtracted so a ratio compares the
calls themselves.
"""

from __future__ import annotations

import timeit
from collections.abc import Mapping
from typing import Any


def ns_per_call(
    cases: Mapping[str, tuple[str, dict[str, Any]]], *, number: int = 200_000, rounds: int = 15
) -> dict[str, float]:
    """{case: ns per execution of its statement}, fastest round, loop overhead removed."""
    timers = {name: timeit.Timer(stmt, globals=env) for name, (stmt, env) in cases.items()}
    empty = timeit.Timer("pass")
    best = {name: float("inf") for name in timers}
    best_empty = float("inf")
    for _ in range(rounds):
        best_empty = min(best_empty, empty.timeit(number))
        for name, timer in timers.items():
            best[name] = min(best[name], timer.timeit(number))
    return {name: max(0.0, (t - best_empty)) / number * 1e9 for name, t in best.items()}
