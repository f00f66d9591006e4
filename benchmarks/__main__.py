"""`make bench`: run every benchmark in one process run and write docs/benchmarks.md.

Each section is a module with `run() -> rows` and `markdown(rows) -> str`, and
optionally `plot(rows, path)`; a section whose module is missing is reported as such.
"""

from __future__ import annotations

import datetime
import importlib
import os
import platform
import sys
import time
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"

SECTIONS = [
    ("dispatch", "Dispatch cost of the COP core (issue 2)"),
    ("compiled_dispatch", "Compiled layer files: static dispatch (issue 3)"),
    ("greeting", "The paper's Table 3: greeting application, plain ROS 2 vs ContextROS"),
    ("activation", "The paper's Fig. 9 extended: activation time vs number of nodes"),
]


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    memory = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        memory = f", {kb / 1024 / 1024:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    return (
        f"{cpu}, {os.cpu_count()} cores{memory}; {platform.system()} {platform.release()}; "
        f"Python {platform.python_version()}"
    )


def main() -> int:
    only = set(sys.argv[1:])
    started = time.time()
    parts = [
        "# Benchmarks",
        "",
        f"- Machine: {machine()}",
        f"- Command: `make bench` (runs `python -m benchmarks`), "
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
        "- Method: cases of a table are measured side by side in one run (interleaved rounds,"
        " fastest round kept); the machine is shared, so ratios matter more than absolutes.",
        "",
    ]
    for name, title in SECTIONS:
        if only and name not in only:
            continue
        parts += [f"## {title}", ""]
        try:
            module = importlib.import_module(f"benchmarks.{name}")
        except ModuleNotFoundError as error:
            if error.name != f"benchmarks.{name}":
                raise
            parts += ["Not measured: this benchmark does not exist yet.", ""]
            continue
        print(f"benchmark: {name} ...", flush=True)
        rows = module.run()
        if getattr(module, "__doc__", None):
            parts += [module.__doc__.strip(), ""]
        parts += [module.markdown(rows), ""]
        if hasattr(module, "plot"):
            image = DOCS / f"bench-{name}.png"
            module.plot(rows, image)
            parts += [f"![{title}]({image.name})", ""]
    parts.append(f"_Total benchmark time: {time.time() - started:.0f} s._")
    DOCS.mkdir(exist_ok=True)
    (DOCS / "benchmarks.md").write_text("\n".join(parts) + "\n")
    print(f"wrote {DOCS / 'benchmarks.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
