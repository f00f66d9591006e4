"""What every part of the C++ parser reads with: the text (tree-sitter's view of it), the
original source, and the diagnostics, located by character offset."""

from __future__ import annotations

from contextros.language.cpp.tokens import SourceText, Token
from contextros.language.diagnostics import DiagnosticSink
from contextros.language.syntax import Position


class Reader:
    """`text` may be the source with some spans blanked (the layer language's items inside a
    block, hidden from tree-sitter): offsets, lines and columns are the source's all the same."""

    def __init__(self, text: SourceText, source: str, sink: DiagnosticSink) -> None:
        self.text = text
        self.source = source
        self.sink = sink

    def error(self, message: str, offset: int) -> None:
        line, col = self.text.position(offset)
        self.sink.error(message, line, col)

    def at(self, offset: int) -> Position:
        return Position(*self.text.position(offset))

    def where(self, token: Token) -> str:
        """`line:col` of a token, as messages name another place."""
        line, col = self.text.position(token.start)
        return f"{line}:{col}"
