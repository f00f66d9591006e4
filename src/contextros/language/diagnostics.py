"""Diagnostics of the layer language: where something is wrong, rendered like a compiler.

Every problem found in a `.layers` file becomes a `Diagnostic` (file, line, column,
severity, message and the quoted source line). Errors stop compilation and are raised
as `LayerSyntaxError`; warnings point at the layer interaction problem and do not.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from contextros.errors import LayerError

_NEWLINE = re.compile(r"\r\n|\r|\n")


class Severity(str, enum.Enum):
    ERROR = "error"
    WARNING = "warning"
    NOTE = "note"  # neither wrong nor suspect: what a check could not do, and why


@dataclass(frozen=True)
class Diagnostic:
    """One finding. `line` and `col` are 1-based, as editors and compilers show them."""

    severity: Severity
    message: str
    path: str
    line: int
    col: int
    source_line: str | None = None  # None: no line to quote (an unreadable or empty file)
    # Found by a parser: an error there comes before the checker's findings, which may only
    # follow from it (a layer whose block was not closed is "unknown" further up).
    syntax: bool = False

    @property
    def is_error(self) -> bool:
        return self.severity is Severity.ERROR

    def render(self) -> str:
        """`file:line:col: error: message`, then the line and a caret under the fault (when
        there is a line to quote)."""
        head = f"{self.path}:{self.line}:{self.col}: {self.severity.value}: {self.message}"
        if self.source_line is None:
            return head
        text = printable(self.source_line)  # quoted even when blank: the caret still says where
        caret = " " * max(0, min(self.col - 1, len(text))) + "^"
        return f"{head}\n    {text}\n    {caret}"

    def sort_key(self) -> tuple[str, bool, int, int, int, str]:
        """By file; its syntax errors first (the real ones: what the checker finds after them
        may follow from them), then by position."""
        rank = list(Severity).index(self.severity)
        follows = not (self.syntax and self.is_error)
        return (self.path, follows, self.line, self.col, rank, self.message)


def printable(source_line: str) -> str:
    """A source line as quoted under a diagnostic: one character per column (a tab is one
    space, as Python counts columns), and no character that would break the quote's line
    or the caret's alignment (form feeds, line separators: shown as '?')."""
    text = source_line.rstrip("\r\n").expandtabs(1)
    return "".join(c if c.isprintable() else "?" for c in text)


class LayerLanguageError(LayerError):
    """Root of the errors of the layer language (all carry file:line:col)."""

    def __init__(self, diagnostics: Sequence[Diagnostic]) -> None:
        if not diagnostics:
            raise ValueError("a LayerLanguageError needs at least one diagnostic")
        self.diagnostics = tuple(diagnostics)
        first = self.diagnostics[0]
        self.path = first.path
        self.line = first.line
        self.col = first.col
        self.message = first.message
        self.source_line = first.source_line
        super().__init__(self._summary())

    def _summary(self) -> str:
        text = self.diagnostics[0].render()
        more = len([d for d in self.diagnostics if d.is_error]) - 1
        return text + (f"\n(and {more} more error{'s' if more > 1 else ''})" if more > 0 else "")

    def render(self) -> str:
        """All diagnostics, one block each."""
        return "\n".join(d.render() for d in self.diagnostics)


class LayerSyntaxError(LayerLanguageError, SyntaxError):
    """A `.layers` file is malformed or inconsistent; compilation refused.

    It is also a `SyntaxError` so that tools that catch those (and the import
    system) treat it like one.
    """

    def __init__(self, diagnostics: Sequence[Diagnostic]) -> None:
        LayerLanguageError.__init__(self, diagnostics)
        # SyntaxError's own attributes, for tools that render them.
        self.filename = self.path
        self.lineno = self.line
        self.offset = self.col
        self.text = self.source_line
        self.msg = self.message

    def __str__(self) -> str:
        return self._summary()


class LayerTargetError(LayerLanguageError):
    """A compiled layer file could not install a layered method on its class.

    Raised at import time, for instance when the class attribute to refine is not a
    function: the compiled module never overwrites such an attribute silently.
    """


def source_lines(source: str) -> list[str]:
    """The lines of a source as Python counts them: only \\n, \\r\\n and \\r end a line.

    (`str.splitlines` also splits at form feeds, \\x1c-\\x1e, \\x85 and \\u2028/9, which
    Python allows inside lines and strings: line numbers would drift.)
    """
    lines = _NEWLINE.split(source)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


class DiagnosticSink:
    """Collects diagnostics for one source text, quoting lines as it goes."""

    def __init__(self, path: str, source: str, *, syntax: bool = False) -> None:
        self.path = path
        self.lines = source_lines(source)
        self.items: list[Diagnostic] = []
        self.syntax = syntax  # a parser's sink (see `Diagnostic.syntax`)

    def quote(self, line: int) -> str | None:
        return self.lines[line - 1] if 1 <= line <= len(self.lines) else None

    def add(self, severity: Severity, message: str, line: int, col: int) -> None:
        # Python reports an unexpected end of file on the line after the last one.
        line = max(1, min(line, len(self.lines) or 1))
        col = max(1, col)
        self.items.append(
            Diagnostic(severity, message, self.path, line, col, self.quote(line), self.syntax)
        )

    def error(self, message: str, line: int, col: int) -> None:
        self.add(Severity.ERROR, message, line, col)

    def warning(self, message: str, line: int, col: int) -> None:
        self.add(Severity.WARNING, message, line, col)

    def note(self, message: str, line: int, col: int) -> None:
        self.add(Severity.NOTE, message, line, col)

    @property
    def has_errors(self) -> bool:
        return any(d.is_error for d in self.items)


def sorted_diagnostics(items: Iterable[Diagnostic]) -> list[Diagnostic]:
    unique = {(d.sort_key(), d.severity): d for d in items}
    return [unique[k] for k in sorted(unique, key=lambda k: k[0])]
