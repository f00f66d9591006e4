"""No silent regressions (issue 26): the ratios of a fresh section against the committed page
it replaces; every one more than 15% worse is listed as REGRESSED with both values.

Only ratios are compared, figures measured side by side in one run: on a shared machine an
absolute time (ns, ms, MiB, commands/s) moves by more than 15% from one hour to the next
with the load, a ratio of two cases measured in the same rounds does not. A figure is a ratio
when its table says so:

- a column "x plain" (dispatch tables: the case against a plain call in the same rounds;
  "1.30 (1.20-1.74)" counts its first number): lower is better;
- a column "... faster by" ("146x (met >= 50x)": ContextROS against ContextPy3): higher is
  better;
- a row "A / B" (the greeting's ContextROS / plain, the target tables' "synchronous at N=64
  / parameter, parallel at N=64"): its numeric cells, lower is better unless the row's
  target says ">= ...".

"Worse by more than 15%": the new value over the old (or the old over the new, where higher
is better) above 1.15.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

THRESHOLD = 1.15
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")
# Lines of the page's head listing the regressions of the last run of each section.
MARK = "- REGRESSED"


@dataclass(frozen=True)
class Figure:
    section: str  # the section's title
    row: str  # the row's first cell
    column: str  # the column's header
    value: float
    higher_is_better: bool

    @property
    def name(self) -> str:
        return f"{self.row}, {self.column}"


@dataclass(frozen=True)
class Regression:
    old: Figure
    new: Figure

    @property
    def factor(self) -> float:
        if self.new.higher_is_better:
            return self.old.value / self.new.value if self.new.value > 0 else float("inf")
        return self.new.value / self.old.value if self.old.value > 0 else float("inf")

    def line(self) -> str:
        return (
            f"{MARK} in {self.new.section}: {self.new.name}: {_number(self.old.value)} -> "
            f"{_number(self.new.value)} ({'higher' if self.new.higher_is_better else 'lower'} "
            f"is better; {self.factor:.2f}x worse)"
        )


def _number(value: float) -> str:
    return f"{value:g}"


def _cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def _first_number(cell: str) -> float | None:
    found = NUMBER.search(cell.replace(",", ""))
    return float(found.group()) if found else None


def _tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """The markdown tables of `text`: (header cells, rows of cells)."""
    lines = text.splitlines()
    tables = []
    for at, line in enumerate(lines[:-1]):
        if line.startswith("|") and lines[at + 1].startswith("|--"):
            rows = []
            for row in lines[at + 2 :]:
                if not row.startswith("|"):
                    break
                rows.append(_cells(row))
            tables.append((_cells(line), rows))
    return tables


def _label(cell: str) -> str:
    return cell.replace("**", "").replace("`", "").strip()


def _unique(header: list[str]) -> list[str]:
    """Column names, a repeated one numbered by its place ("x plain (column 6)")."""
    return [
        f"{name} (column {at + 1})" if name in header[:at] else name
        for at, name in enumerate(header)
    ]


def ratios(section: str, text: str) -> dict[tuple[str, str], Figure]:
    """The ratios in `text` (one section of the page, titled `section`), by (row, column)."""
    found: dict[tuple[str, str], Figure] = {}
    for header, rows in _tables(text):
        for cells in rows:
            row = _label(cells[0])
            ratio_row = " / " in row
            target = next((c for c in cells[1:] if c.startswith((">=", "<="))), "")
            for column, cell in zip(_unique(header)[1:], cells[1:], strict=False):
                if "x plain" in column:
                    higher = False
                elif "faster by" in column:
                    higher = True
                elif ratio_row and not column.startswith(("target", "verdict")):
                    higher = target.startswith(">=")
                else:
                    continue
                value = _first_number(cell)
                if value is None:
                    continue
                found.setdefault((row, column), Figure(section, row, column, value, higher))
    return found


def regressions(section: str, old: str, new: str) -> list[Regression]:
    """The ratios of `new` more than 15% worse than the same ratio in `old`."""
    before = ratios(section, old)
    worse = []
    for key, figure in ratios(section, new).items():
        if key in before:
            change = Regression(before[key], figure)
            if change.factor > THRESHOLD:
                worse.append(change)
    return worse


def head_with(head: str, previous: str, measured: set[str], found: list[Regression]) -> str:
    """`head` (the page's new head) with the REGRESSED lines of the `previous` one for the
    sections not measured in this run, then `found` for the `measured` ones (titles)."""
    lines = [line for line in head.rstrip("\n").splitlines() if not line.startswith(MARK)]
    kept = [
        line
        for line in previous.splitlines()
        if line.startswith(MARK) and not any(line.startswith(f"{MARK} in {t}: ") for t in measured)
    ]
    return "\n".join(lines + kept + [regression.line() for regression in found]) + "\n"
