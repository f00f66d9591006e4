"""`make bench` puts what it measures in place in docs/benchmarks.md and keeps the sections
measured by hand (before/after runs, profiles)."""

from __future__ import annotations

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
