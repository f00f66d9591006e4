"""The C++ dispatch benchmark built twice, from an earlier revision's runtime and from this
checkout's, and run alternately at the same stack offsets: before and after side by side in
one run. Not part of `make bench` (it builds a revision from git); writes its own section of
docs/benchmarks.md, one per issue.

    .venv/bin/python -m benchmarks.cpp_dispatch_before_after [REVISION [ISSUE]]
    # default: main, issue 18

Both builds use this checkout's benchmark sources (cpp/core/benchmarks) and layer compiler,
and align every function to 64 bytes (as the benchmark's own build does), so only the
runtime (cpp/core: layered.hpp and the library) differs. ns per call from the fastest round,
"x plain" the median over the runs of the typical round's ratio to the plain call.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable
from io import BytesIO
from pathlib import Path

from benchmarks.__main__ import machine
from benchmarks.cpp_dispatch import EXECUTABLE, ROOT, STACK_OFFSETS, _tool, measure, splice

TITLE = "C++ dispatch before and after {issue} (one run, two builds)"
# The cases each issue's table shows (every case both builds measured, for another issue).
CASES = {
    "issue 18": [
        "layered: no active layer",
        "layered: one partial, no proceed",
        "layered: one partial, proceeds",
        "layered: three partials, proceed",
        "atomic function pointer: one partial, no proceed",
        "plain out-of-line call",
    ],
    "issue 26": [
        "plain member call",
        "layered method: one partial, no proceed",
        "layered method: one partial, for the object (activate_for)",
        "layered method: one partial, another object with layers of its own",
        "layered method: one partial, another object whose own layers change its chain",
        "layered: one partial, no proceed",
        "layered: one partial, proceeds",
        "layered: three partials, proceed",
        "layered: one partial, no proceed, scoped (ScopedActivation)",
        "atomic function pointer: one partial, no proceed",
        "plain out-of-line call",
    ],
}


def _build(source: Path, build: Path) -> Path:
    cmake = _tool("cmake")
    compiler = Path(sys.executable).parent / "contextros"
    subprocess.run(
        [cmake, "-S", str(source / "cpp" / "core"), "-B", str(build), "-G", "Ninja",
         "-DCMAKE_BUILD_TYPE=Release", "-DCONTEXTROS_CORE_TESTS=OFF",
         "-DCMAKE_CXX_FLAGS=-falign-functions=64", f"-DCONTEXTROS_COMPILER={compiler}"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    subprocess.run(
        [cmake, "--build", str(build), "--target", EXECUTABLE, "--parallel", "2"],
        check=True,
        capture_output=True,
        text=True,
    )
    return build / EXECUTABLE


def _checkout(revision: str | None, into: Path) -> None:
    """cpp/ of `revision` (None: this checkout's files) into `into`, with this checkout's
    benchmark sources."""
    if revision is None:
        archive = subprocess.run(
            ["tar", "-c", "-C", str(ROOT), "cpp"], check=True, capture_output=True
        ).stdout
    else:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", "--format=tar", revision, "cpp"],
            check=True,
            capture_output=True,
        ).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    for path in (ROOT / "cpp" / "core" / "benchmarks").iterdir():
        (into / "cpp" / "core" / "benchmarks" / path.name).write_bytes(path.read_bytes())


def run(revision: str = "main") -> dict[str, dict[str, list[tuple[float, float]]]]:
    runs: dict[str, dict[str, list[tuple[float, float]]]] = {"before": {}, "after": {}}
    with tempfile.TemporaryDirectory() as work:
        executables = {}
        for name, rev in (("before", revision), ("after", None)):
            _checkout(rev, Path(work) / name)
            executables[name] = _build(Path(work) / name, Path(work) / f"build-{name}")
        for offset in STACK_OFFSETS:
            for name in ("before", "after"):
                measure(executables[name], offset, runs[name])
    return runs


def markdown(
    runs: dict[str, dict[str, list[tuple[float, float]]]], revision: str, issue: str = "issue 18"
) -> str:
    lines = [
        f"| case | before ({revision}) ns | x plain, median | after ns | x plain, median |",
        "|---|---:|---:|---:|---:|",
    ]
    shown = CASES.get(issue) or [case for case in runs["after"] if case in runs["before"]]
    for case in shown:
        if case not in runs["before"]:
            continue
        cells = []
        for name in ("before", "after"):
            results = runs[name][case]
            cells.append(
                f"{min(ns for ns, _ in results):.2f} | "
                f"{statistics.median(r for _, r in results):.2f}"
            )
        lines.append(f"| {case} | {' | '.join(cells)} |")

    def fastest(name: str, case: str) -> float:
        return min(ns for ns, _ in runs[name][case])

    lines += [
        "",
        *(_issue_26 if issue == "issue 26" else _issue_18)(fastest),
        "",
        f"Machine: {machine()}, shared (load average "
        f"{os.getloadavg()[0]:.1f} when written); command: `.venv/bin/python -m "
        f"benchmarks.cpp_dispatch_before_after {revision} '{issue}'`.",
    ]
    return "\n".join(lines)


Fastest = Callable[[str, str], float]


def _issue_18(fastest: Fastest) -> list[str]:
    floor = fastest("after", "atomic function pointer: one partial, no proceed")
    call = fastest("after", "layered: one partial, no proceed")
    one = fastest("after", "layered: one partial, proceeds") - fastest(
        "before", "layered: one partial, proceeds"
    )
    three = fastest("after", "layered: three partials, proceed") - fastest(
        "before", "layered: three partials, proceed"
    )
    return [
        f"After: a layered call without proceed costs {call:.2f} ns, the atomic function "
        f"pointer {floor:.2f} ns (one load, one indirect call: the same instructions). "
        f"Before, the second, dependent load cost "
        f"{fastest('before', 'layered: one partial, no proceed') - floor:+.2f} ns in this "
        "loop (the indirect call's target is predicted, so the load is off the critical "
        f"path). A call whose head proceeds costs {one:+.2f} ns after (one partial), "
        f"{three:+.2f} ns (three partials): the head's proceed goes through one more "
        "indirect call to find its chain."
    ]


def _issue_26(fastest: Fastest) -> list[str]:
    def member(name: str, case: str) -> str:
        return f"{fastest(name, case) / fastest(name, 'plain member call'):.2f}x"

    method = "layered method: one partial, no proceed"
    own = "layered method: one partial, for the object (activate_for)"
    other = "layered method: one partial, another object with layers of its own"
    refining = "layered method: one partial, another object whose own layers change its chain"
    return [
        f"A plain member call's multiple, fastest rounds, before -> after: a layered method "
        f"{member('before', method)} -> {member('after', method)} (target <= 1.3x); for its "
        f"object only {member('before', own)} -> {member('after', own)} (target <= 3x); while "
        f"another object has layers of its own {member('before', other)} -> "
        f"{member('after', other)}, that change the method's chain "
        f"{member('before', refining)} -> {member('after', refining)}. A free function with "
        f"one partial: {fastest('before', 'layered: one partial, no proceed'):.2f} -> "
        f"{fastest('after', 'layered: one partial, no proceed'):.2f} ns, the atomic function "
        f"pointer {fastest('after', 'atomic function pointer: one partial, no proceed'):.2f} "
        "ns."
    ]


if __name__ == "__main__":
    revision = sys.argv[1] if len(sys.argv) > 1 else "main"
    issue = sys.argv[2] if len(sys.argv) > 2 else "issue 18"
    table = markdown(run(revision), revision, issue)
    print(table)
    splice(f"{(__doc__ or '').strip()}\n\n{table}", title=TITLE.format(issue=issue))
