"""`make bench` puts what it measures in place in docs/benchmarks.md and keeps the sections
measured by hand (before/after runs, profiles); `python -m benchmarks` itself (issue 25) and
its regression list (issue 26)."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import benchmarks.__main__ as runner
import pytest
from benchmarks import regressions
from benchmarks.__main__ import KEEP, SECTIONS, _splice

MEASURED = SECTIONS[0][1]
PAGE = f"# Benchmarks\n\nold head\n\n## {MEASURED}\n\nold table\n\n## By hand\n\nkept\n"
FRESH = f"# Benchmarks\n\nnew head\n\n## {MEASURED}\n\nnew table\n\n_Total benchmark time: 1 s._\n"


def test_a_full_run_replaces_its_sections_and_the_head_and_keeps_the_rest() -> None:
    page = _splice(PAGE, FRESH, {name for name, _ in SECTIONS}, fresh_head=True)
    assert page == f"# Benchmarks\n\nnew head\n\n## {MEASURED}\n\nnew table\n\n## By hand\n\nkept\n"


def test_a_run_of_some_sections_keeps_the_head() -> None:
    page = _splice(PAGE, FRESH, {SECTIONS[0][0]})
    assert page.startswith("# Benchmarks\n\nold head\n") and "new table" in page
    assert "old table" not in page and "kept" in page


def test_what_a_measured_section_keeps_below_its_line_stays() -> None:
    page = PAGE.replace("old table\n", f"old table\n\n{KEEP}\n\nnotes by hand\n")
    renewed = _splice(page, FRESH, {name for name, _ in SECTIONS}, fresh_head=True)
    assert f"## {MEASURED}\n\nnew table\n\n{KEEP}\n\nnotes by hand\n" in renewed
    assert "old table" not in renewed and "## By hand\n\nkept\n" in renewed


# `python -m benchmarks` itself (issue 25): usage, unknown sections, a failing section.


ROOT = Path(__file__).resolve().parent.parent


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "benchmarks", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_help_prints_the_usage_and_every_section() -> None:
    done = _cli("--help")
    assert done.returncode == 0
    assert done.stdout.startswith("usage: python -m benchmarks [SECTION ...]")
    assert all(name in done.stdout for name, _ in SECTIONS)
    assert "updated" not in done.stdout


def test_an_unknown_section_exits_2_listing_the_sections() -> None:
    done = _cli("dispatch", "nonexistent")
    assert done.returncode == 2
    assert "unknown section(s) nonexistent" in done.stderr
    assert all(name in done.stderr for name, _ in SECTIONS)
    assert "updated" not in done.stdout


def _section(title: str, table: str) -> str:
    return f"## {title}\n\nintro\n\n{table}\n"


TABLE = "| case | ns/call | x plain | ContextROS faster by |\n|---|---:|---:|---:|\n"


def _fake(monkeypatch: pytest.MonkeyPatch, sections: dict[str, object]) -> None:
    """Sections `name: run()'s rows, or an exception it raises` as modules of the runner."""
    monkeypatch.setattr(runner, "SECTIONS", [(name, f"Fake {name}") for name in sections])
    for name, outcome in sections.items():

        def run(outcome: object = outcome) -> object:
            if isinstance(outcome, Exception):
                raise outcome
            return outcome

        module = types.ModuleType(f"benchmarks.{name}")
        module.run = run  # type: ignore[attr-defined]
        module.markdown = lambda rows: (
            TABLE
            + "".join(  # type: ignore[attr-defined]
                f"| {case} | {ns} | {ratio} | {faster} |\n" for case, ns, ratio, faster in rows
            )
        )
        monkeypatch.setitem(sys.modules, f"benchmarks.{name}", module)


def test_a_failing_section_is_reported_and_the_others_are_written(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    page = tmp_path / "benchmarks.md"
    old_rows = "| plain | 10 | 1.00 | |\n"
    page.write_text(
        "# Benchmarks\n\nold head\n- REGRESSED in Fake dashboard: switch, x plain: 1 -> 2\n\n"
        + _section("Fake first", TABLE + old_rows)
        + "\n"
        + _section("Fake dashboard", TABLE + "| switch | 5 | 1.00 | |\n")
        + "\n"
        + _section("Fake last", TABLE + old_rows)
    )
    missing = ModuleNotFoundError("No module named 'playwright'", name="playwright")
    _fake(
        monkeypatch,
        {
            "first": [("plain", 11, 1.0, "")],
            "dashboard": missing,
            "last": [("plain", 12, 1.0, "")],
        },
    )
    assert runner.main([], page=page) == 1
    text = page.read_text()
    assert "| plain | 11 |" in text and "| plain | 12 |" in text
    assert "| switch | 5 | 1.00 | |" in text  # the failed section keeps its results
    assert "Not measured in this run" in text and "dashboard (ModuleNotFoundError" in text
    assert "- REGRESSED in Fake dashboard: switch" in text  # its earlier list stays too
    assert "dashboard: ModuleNotFoundError: No module named 'playwright'" in capsys.readouterr().err


# No silent regressions (issue 26): ratios against the page a run replaces.

OLD = TABLE + (
    "| plain method | 35.4 | 1.00 |  |\n"
    "| one partial, proceeds | 71.6 | 2.02 | 110x (met >= 50x) |\n"
    "| three partials, proceed | 164.7 | 4.65 | 69x (met >= 50x) |\n"
    "| scoped | 160.8 | 4.54 | 46x |\n"
)
NEW = TABLE + (
    "| plain method | 20.0 | 1.00 |  |\n"  # absolute: twice as fast, not compared
    "| one partial, proceeds | 140.0 | 2.40 | 100x (met >= 50x) |\n"  # 1.19x worse
    "| three partials, proceed | 320.0 | 5.30 | 58x (met >= 50x) |\n"  # 1.14x worse; 1.19x
    "| scoped | 300.0 | 4.00 | 52x |\n"  # better
)


def test_only_ratios_more_than_15_percent_worse_are_regressions() -> None:
    found = {(r.new.row, r.new.column): r for r in regressions.regressions("T", OLD, NEW)}
    assert set(found) == {
        ("one partial, proceeds", "x plain"),
        ("three partials, proceed", "ContextROS faster by"),
    }
    line = found[("one partial, proceeds", "x plain")].line()
    assert line.startswith("- REGRESSED in T: one partial, proceeds, x plain: 2.02 -> 2.4 ")
    assert "(lower is better; 1.19x worse)" in line
    assert "69 -> 58 (higher is better; 1.19x worse)" in (
        found[("three partials, proceed", "ContextROS faster by")].line()
    )


def test_ratio_rows_and_their_targets() -> None:
    table = "| target | measured | target | verdict |\n|---|---:|---:|---|\n"
    old = table + (
        "| atomic at N=64 / synchronous at N=64 | 1.96 | <= 2 | met |\n"
        "| share / all | 1.00 | >= 0.9 | met |\n"
        "| synchronous at N=64, median ms | 10.0 | <= 15 | met |\n"
    )
    new = table + (
        "| atomic at N=64 / synchronous at N=64 | 2.30 | <= 2 | MISSED |\n"
        "| share / all | 0.80 | >= 0.9 | MISSED |\n"
        "| synchronous at N=64, median ms | 20.0 | <= 15 | MISSED |\n"
    )
    found = regressions.regressions("T", old, new)
    assert [(r.new.row, r.new.column, r.new.higher_is_better) for r in found] == [
        ("atomic at N=64 / synchronous at N=64", "measured", False),
        ("share / all", "measured", True),
    ]


def test_a_run_lists_its_regressions_at_the_top_and_at_its_end(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    page = tmp_path / "benchmarks.md"
    page.write_text(
        "# Benchmarks\n\n- Machine: old\n- REGRESSED in Fake other: kept, x plain: 1 -> 2\n"
        "- REGRESSED in Fake dispatch: stale, x plain: 1 -> 2\n\n"
        + _section("Fake dispatch", OLD)
        + "\n"
        + _section("Fake other", TABLE)
    )
    rows = [
        ("plain method", 20.0, "1.00", ""),
        ("one partial, proceeds", 140.0, "2.40", "100x"),
        ("three partials, proceed", 320.0, "5.30", "69x"),
        ("scoped", 300.0, "4.00", "52x"),
    ]
    _fake(monkeypatch, {"dispatch": rows, "other": []})
    assert runner.main(["dispatch"], page=page) == 0
    head = page.read_text().split("\n## ")[0]
    assert "- REGRESSED in Fake dispatch: one partial, proceeds, x plain: 2.02 -> 2.4 " in head
    assert "stale" not in head  # the section's earlier list is replaced
    assert "- REGRESSED in Fake other: kept" in head  # another section's stays
    out = capsys.readouterr().out
    assert out.rstrip().endswith("(lower is better; 1.19x worse)")
    assert "1 ratio(s) more than 15% worse" in out
