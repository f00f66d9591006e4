"""C++ text as tree-sitter reads it: tokens, positions and sub-trees of a layer file.

Positions in a layer file are characters, tree-sitter's are UTF-8 bytes: `SourceText`
converts between them and turns character offsets into 1-based lines and columns counted
the way the diagnostics count them.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache

import tree_sitter
import tree_sitter_cpp

# Nodes read as one token: their insides are not C++ tokens.
OPAQUE = frozenset(
    {
        "comment",
        "string_literal",
        "raw_string_literal",
        "char_literal",
        "system_lib_string",
    }
)


# Every byte but line ends becomes a space.
_BLANK = bytes(b if b in (10, 13) else 32 for b in range(256))


@cache
def _parser() -> tree_sitter.Parser:
    return tree_sitter.Parser(tree_sitter.Language(tree_sitter_cpp.language()))


@dataclass(frozen=True)
class Token:
    kind: str  # the tree-sitter node type ("identifier", "[", "comment"...)
    text: str
    start: int  # character offsets in the layer file
    end: int


class SourceText:
    """A layer file's text with its byte/character and line/column maps."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.data = source.encode("utf-8", errors="surrogatepass")
        self.ascii = len(self.data) == len(source)
        self._byte_of_char: list[int] = []
        if not self.ascii:
            offsets = [0]
            for char in source:
                offsets.append(offsets[-1] + len(char.encode("utf-8", errors="surrogatepass")))
            self._byte_of_char = offsets
        self.line_starts = [0]
        i = 0
        while i < len(source):
            char = source[i]
            if char == "\r" and i + 1 < len(source) and source[i + 1] == "\n":
                i += 1
            if char in "\r\n":
                self.line_starts.append(i + 1)
            i += 1

    def char(self, byte: int) -> int:
        if self.ascii:
            return byte
        return bisect.bisect_left(self._byte_of_char, byte)

    def byte(self, char: int) -> int:
        return char if self.ascii else self._byte_of_char[char]

    def position(self, char: int) -> tuple[int, int]:
        """1-based (line, column) of a character offset."""
        row = bisect.bisect_right(self.line_starts, char) - 1
        return row + 1, char - self.line_starts[row] + 1

    def line_start(self, line: int) -> int:
        return self.line_starts[line - 1] if line - 1 < len(self.line_starts) else len(self.source)

    def parse(self, start: int = 0, end: int | None = None) -> tree_sitter.Tree:
        """tree-sitter's tree of source[start:end], every other byte blanked: positions hold."""
        stop = len(self.source) if end is None else end
        first, last = self.byte(start), self.byte(stop)
        data = self.data
        blanked = data[:first].translate(_BLANK) + data[first:last] + data[last:].translate(_BLANK)
        return _parser().parse(blanked)

    def text(self, node: tree_sitter.Node) -> str:
        return self.source[self.char(node.start_byte) : self.char(node.end_byte)]

    def span(self, node: tree_sitter.Node) -> tuple[int, int]:
        return self.char(node.start_byte), self.char(node.end_byte)


def leaves(node: tree_sitter.Node) -> Iterator[tree_sitter.Node]:
    """The tokens under `node` in order (opaque nodes whole, zero-width MISSING ones skipped)."""
    stack = [node]
    while stack:
        current = stack.pop()
        if current.is_missing or current.start_byte == current.end_byte:
            continue
        if current.child_count == 0 or current.type in OPAQUE:
            yield current
            continue
        stack.extend(reversed(current.children))


def tokens(text: SourceText, start: int, end: int) -> tuple[list[Token], int | None]:
    """The tokens of source[start:end], and the offset of a character no token covers."""
    tree = text.parse(start, end)
    found: list[Token] = []
    position = start
    for leaf in leaves(tree.root_node):
        first, last = text.span(leaf)
        if first < start or first >= end:
            continue
        gap = text.source[position:first]
        if gap.strip():
            return found, position + (len(gap) - len(gap.lstrip()))
        found.append(Token(leaf.type, text.source[first:last], first, last))
        position = max(position, last)
    gap = text.source[position:end]
    if gap.strip():
        return found, position + (len(gap) - len(gap.lstrip()))
    return found, None


def first_problem(node: tree_sitter.Node) -> tree_sitter.Node | None:
    """The first ERROR or MISSING node under `node`, in document order."""
    if not node.has_error:
        return None
    stack = [node]
    while stack:
        current = stack.pop()
        if current.is_error or current.is_missing:
            return current
        stack.extend(reversed([c for c in current.children if c.has_error or c.is_missing]))
    return None


def identifier_char(char: str) -> bool:
    return char == "_" or char.isalnum()
