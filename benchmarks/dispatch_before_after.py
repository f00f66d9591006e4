"""The dispatch section's cases for the code before and the code now, side by side in one run.

`CONTEXTROS_BEFORE=<a source tree> python -m benchmarks.dispatch_before_after [rounds]` runs
benchmarks/dispatch.py's cases in child processes, round by round: the code before, the code
now with its C dispatcher, and with its pure-Python one (CONTEXTROS_PURE_PYTHON=1). Each
variant keeps its fastest time per case over the rounds, as x its own fastest plain call.

With `--instructions` (valgrind needed) it counts the instructions of one call of each case
instead (callgrind, the same child process run with 0 and with N calls: the difference per
call, a plain call's loop subtracted): the noise-free comparison on a shared machine.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from benchmarks.code_before import before_environment

ROOT = Path(__file__).resolve().parent.parent
CASES = {
    "one partial, proceeds": "proceeds",
    "one guarded partial (guard true), proceeds": "guarded",
    "one partial, proceeds, scoped (with activated)": "scoped",
    "one partial, proceeds, per-object (activate_for)": "per-object",
    "reference: one partial, proceeds, behind one more plain frame": "floor",
}
# One child's calls of one case (instructions mode): argv = case, number of calls.
CALLS = """
import sys
from benchmarks.dispatch import Elsewhere, Floor, Guarded, L1, Layered, Plain
from contextros import activate_for, activated, set_active

case, n = sys.argv[1], int(sys.argv[2])
elsewhere = Elsewhere()
activate_for(elsewhere, L1)


def calls(o, n):
    for _ in range(n):
        o.step(1)


def loop(o, n):
    for _ in range(n):
        o


if case == "loop":
    loop(Plain(), n)
elif case == "plain":
    calls(Plain(), n)
elif case in ("proceeds", "guarded"):
    set_active([L1])
    calls(Layered() if case == "proceeds" else Guarded(), n)
elif case in ("scoped", "floor"):
    with activated(L1):
        calls(Layered() if case == "scoped" else Floor(), n)
elif case == "per-object":
    calls(elsewhere, n)
"""
TIMES = (
    "import json; from benchmarks.dispatch import _contextros_cases; "
    "print(json.dumps(_contextros_cases()))"
)


def variants(tree: Path) -> dict[str, dict[str, str]]:
    now = {"PYTHONPATH": str(ROOT)}
    return {
        "before": before_environment(tree),
        "now, C": now | {"CONTEXTROS_PURE_PYTHON": "0"},
        "now, pure Python": now | {"CONTEXTROS_PURE_PYTHON": "1"},
    }


def _dispatcher(environment: dict[str, str]) -> str:
    shown = subprocess.run(
        [sys.executable, "-c", "import contextros.core as c; print(c.DISPATCHER)"],
        env=os.environ | environment,
        capture_output=True,
        text=True,
        cwd=ROOT,
    ).stdout.strip()
    return shown or "python (no DISPATCHER: the code before)"


def times(tree: Path, rounds: int) -> dict[str, dict[str, float]]:
    best: dict[str, dict[str, float]] = {}
    for _ in range(rounds):
        for name, environment in variants(tree).items():
            done = subprocess.run(
                [sys.executable, "-c", TIMES],
                env=os.environ | environment,
                capture_output=True,
                text=True,
                check=True,
                cwd=ROOT,
            )
            measured = json.loads(done.stdout)
            kept = best.setdefault(name, measured)
            for case, ns in measured.items():
                kept[case] = min(kept[case], ns)
    return best


def _instructions(environment: dict[str, str], case: str, calls: int) -> int:
    done = subprocess.run(
        [
            "valgrind",
            "--tool=callgrind",
            "--trace-children=yes",
            "--callgrind-out-file=/dev/null",
            sys.executable,
            "-c",
            CALLS,
            case,
            str(calls),
        ],
        env=os.environ | environment,
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    found = re.findall(r"Collected : (\d+)", done.stderr)
    return int(found[-1])


def instructions(tree: Path, calls: int = 20_000) -> dict[str, dict[str, float]]:
    counted: dict[str, dict[str, float]] = {}
    for name, environment in variants(tree).items():
        per_call = {}
        for case in ["loop", "plain", *CASES.values()]:
            more = _instructions(environment, case, calls)
            per_call[case] = (more - _instructions(environment, case, 0)) / calls
        loop = per_call.pop("loop")
        counted[name] = {case: count - loop for case, count in per_call.items()}
    return counted


def table(measured: dict[str, dict[str, float]], unit: str, keys: dict[str, str]) -> str:
    names = list(measured)
    lines = [
        "| case | " + " | ".join(f"{name} {unit} | x plain" for name in names) + " |",
        "|---|" + "---:|---:|" * len(names),
        *(
            f"| {case} | "
            + " | ".join(
                f"{measured[name][key]:.0f} | {measured[name][key] / measured[name]['plain']:.2f}"
                for name in names
            )
            + " |"
            for case, key in [("plain method", "plain"), *keys.items()]
        ),
    ]
    return "\n".join(lines)


def main() -> None:
    tree = os.environ.get("CONTEXTROS_BEFORE")
    if not tree:
        sys.exit("set CONTEXTROS_BEFORE=<a source tree of the code before> (a git worktree)")
    for name, environment in variants(Path(tree)).items():
        print(f"{name}: dispatcher {_dispatcher(environment)}")
    if "--instructions" in sys.argv:
        if shutil.which("valgrind") is None:
            sys.exit("--instructions needs valgrind")
        print(table(instructions(Path(tree)), "instructions", CASES))
        return
    numbers = [argument for argument in sys.argv[1:] if argument.isdigit()]
    rounds = int(numbers[0]) if numbers else 3
    print(table(times(Path(tree), rounds), "ns", {case: case for case in CASES}))


if __name__ == "__main__":
    main()
