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
    (
        "cpp_dispatch",
        "C++ dispatch: generated layered calls vs a plain call vs Listing 2 (issue 9)",
    ),
    ("greeting", "The paper's Table 3: greeting application, plain ROS 2 vs ContextROS"),
    ("activation", "The paper's Fig. 9 extended: activation time vs number of nodes"),
    ("cpp_activation", "C++ context nodes: activation round trip, memory, start-up (issue 9)"),
    ("lossy_link", "Synchronous activation over a lossy link between two hosts (issue 10)"),
    ("rules", "Context rules: manager-side cost per message (issue 11)"),
    ("cli_command", "A CLI client command, from process start to exit (issue 12)"),
    ("simulation", "The protocol at fleet scale, simulated: cost vs number of nodes (issue 16)"),
    ("manager_cost", "The manager's CPU per synchronous activation, before/after (issue 16)"),
    (
        "participant_cost",
        "The participants' CPU per synchronous activation: rclpy's executor vs lean spin "
        "(issue 16)",
    ),
    ("storm", "A storm of commands from 3 clients: throughput, exactness, memory (issue 16)"),
    ("dashboard", "The dashboard: a switch on the page, and an open page over time (issue 17)"),
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
    target = DOCS / "benchmarks.md"
    if target.exists():
        # The measured sections in place in the existing page; the others, and the sections
        # measured by hand (before/after runs, profiles), kept as they were.
        measured = only or {name for name, _ in SECTIONS}
        text = _splice(target.read_text(), "\n".join(parts) + "\n", measured, not only)
        target.write_text(text)
        print(f"updated {sorted(measured)} in {target}")
        return 0
    target.write_text("\n".join(parts) + "\n")
    print(f"wrote {DOCS / 'benchmarks.md'}")
    return 0


def _sections(text: str) -> tuple[str, dict[str, str]]:
    """The page's head and its `## ` sections by title."""
    head, *chunks = text.split("\n## ")
    return head, {chunk.split("\n", 1)[0]: "## " + chunk for chunk in chunks}


def _splice(page: str, fresh: str, only: set[str], fresh_head: bool = False) -> str:
    """`page` with the sections of `fresh` replaced in place (new ones appended), the others
    kept as they were; with `fresh_head` (a full run), the page's head (machine, command,
    date) is `fresh`'s too."""
    head, old = _sections(page)
    new_head, new = _sections(fresh.split("\n_Total benchmark time")[0])
    head = new_head if fresh_head else head
    titles = {title for name, title in SECTIONS if name in only}
    merged = [
        _renewed(section, new[title]) if title in titles and title in new else section
        for title, section in old.items()
    ]
    merged += [new[title] for title in new if title in titles and title not in old]
    return head.rstrip() + "\n\n" + "\n".join(s.rstrip() + "\n" for s in merged).rstrip() + "\n"


# In a measured section, what follows this line was measured or written by hand (earlier
# runs, before/after comparisons, explanations): a run renews what comes before it only.
KEEP = "<!-- by hand: `make bench` renews what is above this line and keeps what follows -->"


def _renewed(section: str, fresh: str) -> str:
    """`fresh` in place of `section`, with what `section` keeps below its KEEP line."""
    if KEEP not in section:
        return fresh
    return fresh.rstrip() + "\n\n" + section[section.index(KEEP) :]


if __name__ == "__main__":
    sys.exit(main())
