"""`make bench`: run every benchmark in one process run and write docs/benchmarks.md.

Each section is a module with `run() -> rows` and `markdown(rows) -> str`, and
optionally `plot(rows, path)`. `python -m benchmarks --help` lists them.
"""

from __future__ import annotations

import datetime
import importlib
import os
import platform
import sys
import time
import traceback
from pathlib import Path

from benchmarks import regressions

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


USAGE = """usage: python -m benchmarks [SECTION ...]

Runs the benchmark sections (all of them, in this order, without SECTION) and writes what
they measure into docs/benchmarks.md: each measured section in place, the others kept. The
page is written after every section; a section that fails is reported, keeps its previous
results, and the run goes on (exit status 1 at the end). Every ratio more than 15% worse
than on the page it replaces is listed at the page's top and at the end of the run
(REGRESSED). `make bench` installs what the sections need first.

sections:
{sections}"""


def usage() -> str:
    width = max(len(name) for name, _ in SECTIONS)
    return USAGE.format(
        sections="\n".join(f"  {name:<{width}}  {title}" for name, title in SECTIONS)
    )


def main(argv: list[str] | None = None, page: Path | None = None) -> int:
    """Runs the sections named in `argv` (all without), writing `page` after each one."""
    args = sys.argv[1:] if argv is None else argv
    if any(arg in ("-h", "--help") for arg in args):
        print(usage())
        return 0
    names = [name for name, _ in SECTIONS]
    unknown = [arg for arg in args if arg not in names]
    if unknown:
        print(
            f"benchmarks: unknown section(s) {', '.join(unknown)}; the sections are: "
            f"{', '.join(names)} (python -m benchmarks --help)",
            file=sys.stderr,
        )
        return 2
    target = page or DOCS / "benchmarks.md"
    started = time.time()
    only = set(args)
    selected = [(name, title) for name, title in SECTIONS if not only or name in only]
    original = target.read_text() if target.exists() else ""
    fresh: dict[str, str] = {}  # by section name, as measured in this run
    failed: dict[str, str] = {}
    found: list[regressions.Regression] = []
    for name, title in selected:
        print(f"benchmark: {name} ...", flush=True)
        try:
            fresh[name] = _measure(name, title, target.parent)
        except KeyboardInterrupt:
            failed[name] = "interrupted"
            _write(target, original, fresh, failed, found, full=not only)
            raise
        except Exception as error:  # one section's failure must not lose the others
            traceback.print_exc()
            failed[name] = f"{type(error).__name__}: {error}".splitlines()[0]
            print(f"benchmark: {name} FAILED ({failed[name]}); going on", file=sys.stderr)
            continue
        old = _sections(original)[1].get(title, "").split(KEEP)[0]
        found += regressions.regressions(title, old, fresh[name])
        _write(target, original, fresh, failed, found, full=not only)
    print(f"updated {sorted(fresh)} in {target} ({time.time() - started:.0f} s)")
    if found:
        print(f"{len(found)} ratio(s) more than 15% worse than on the page this run replaced:")
        for regression in found:
            print(f"  {regression.line()[2:]}")
    if failed:
        print(f"{len(failed)} section(s) FAILED (their previous results kept):", file=sys.stderr)
        for name, why in failed.items():
            print(f"  {name}: {why}", file=sys.stderr)
        return 1
    return 0


def _measure(name: str, title: str, docs: Path) -> str:
    """One section's markdown, measured now."""
    module = importlib.import_module(f"benchmarks.{name}")
    rows = module.run()
    parts = [f"## {title}", ""]
    if getattr(module, "__doc__", None):
        parts += [module.__doc__.strip(), ""]
    parts += [module.markdown(rows), ""]
    if hasattr(module, "plot"):
        image = docs / f"bench-{name}.png"
        module.plot(rows, image)
        parts += [f"![{title}]({image.name})", ""]
    return "\n".join(parts)


def _head(failed: dict[str, str]) -> str:
    lines = [
        "# Benchmarks",
        "",
        f"- Machine: {machine()}",
        f"- Command: `make bench` (runs `python -m benchmarks`), "
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
        "- Method: cases of a table are measured side by side in one run (interleaved rounds,"
        " fastest round kept); the machine is shared, so ratios matter more than absolutes.",
        "- Regressions: every ratio more than 15% worse than on the page a run replaced is"
        " listed here as REGRESSED (benchmarks/regressions.py says which figures are ratios).",
    ]
    if failed:
        lines.append(
            "- Not measured in this run (failed; their sections keep earlier results): "
            + ", ".join(f"{name} ({why})" for name, why in failed.items())
        )
    return "\n".join(lines) + "\n"


def _write(
    target: Path,
    original: str,
    fresh: dict[str, str],
    failed: dict[str, str],
    found: list[regressions.Regression],
    full: bool,
) -> None:
    """The page: `original` with the `fresh` sections in place and the regressions (of the
    sections measured) in its head; with `full` (every section run), the head renewed."""
    titles = dict(SECTIONS)
    text = _head(failed) + "".join("\n" + fresh[name] for name in fresh)
    if original:
        text = _splice(original, text, set(fresh), full)
    head, rest = text.split("\n## ", 1) if "\n## " in text else (text, None)
    previous = _sections(original)[0] if original else ""
    head = regressions.head_with(head, previous, {titles[name] for name in fresh}, found)
    text = head.rstrip() + "\n" + ("\n## " + rest if rest is not None else "")
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(text)


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
