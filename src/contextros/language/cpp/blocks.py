"""A `Layer X [ ... ]` or `base [ ... ]` block of a C++ layer file: where it ends (its
brackets paired, an unclosed or stray one reported where it is), the layer language's items
inside it (a description, `on activate { ... }` hooks, `when (CONDITION)` guards) and its
function definitions."""

from __future__ import annotations

from dataclasses import dataclass, field

from contextros.language.cpp.functions import FunctionReader, GuardSpan
from contextros.language.cpp.names import DECLARATION_WORDS
from contextros.language.cpp.reading import Reader
from contextros.language.cpp.tokens import SourceText, Token
from contextros.language.cpp.tree import CppHook, Span
from contextros.language.syntax import Function, LayerDecl

# What closes each bracket; a closing bracket of more strength than the open one's ends it
# too (a '}' ends a '(').
_CLOSER = {"(": ")", "[": "]", "{": "}", "[[": "]]"}
_STRENGTH = {")": 0, "]": 1, "]]": 1, "}": 2}
_STRINGS = ("string_literal", "raw_string_literal")
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "\\": "\\", '"': '"', "'": "'", "0": "\0"}


@dataclass
class BlockItems:
    """What a block holds besides function definitions, found in its tokens: spans to hide
    from tree-sitter (each item is the layer language's, not C++) and the guards."""

    masks: list[Span] = field(default_factory=list)
    broken: bool = False  # an item was reported: the block's C++ is not parsed
    guards: list[GuardSpan] = field(default_factory=list)


@dataclass
class _Scan:
    """One block's tokens as its items are read: from its '[' to its ']' (at `end`)."""

    tokens: list[Token]
    end: int
    layer: LayerDecl | None
    items: BlockItems

    @property
    def where(self) -> str:
        return f"layer {self.layer.name}" if self.layer is not None else "the base block"

    def closing(self, start: int) -> int:
        """The index of the bracket closing the one at `start` (`end` if none does)."""
        opening = self.tokens[start].text
        depth = 0
        close = start
        while close < self.end:
            depth += {opening: 1, _CLOSER[opening]: -1}.get(self.tokens[close].text, 0)
            if depth == 0:
                break
            close += 1
        return close


class BlockReader(Reader):
    def end(self, found: list[Token], open_index: int) -> tuple[int | None, bool]:
        """The index of the `]` closing the block opened at `open_index`, and whether the
        brackets inside it pair up (an error was reported where they do not). None: the block
        is not closed (reported at the declaration word that comes instead, or at its `[`)."""
        opened: list[Token] = []  # '(', '[' and '{' inside the block, innermost last
        paired = True
        for k in range(open_index + 1, len(found)):
            token = found[k]
            text = token.text
            column_one = self.text.position(token.start)[1] == 1
            if column_one and text in DECLARATION_WORDS and not opened:
                self.error(
                    f"expected ']' before {text!r}: the block opened at "
                    f"{self.where(found[open_index])} is not closed",
                    token.start,
                )
                return None, False
            if text in ("(", "[", "{", "[["):
                opened.append(token)
                continue
            if text not in (")", "]", "}", "]]"):
                continue
            if text in ("]", "]]") and (not opened or (column_one and text == "]")):
                if opened and paired:
                    self._unclosed(opened[-1])
                if text == "]]" and not opened:
                    self.error("']]' closes the block and an inner '[' at once", token.start)
                    return None, False
                return k, paired and not opened
            if not opened:
                # A '}' whose '{' is missing: C++'s grammar finds where the '{' belonged.
                if paired and text != "}":
                    self.error(f"unmatched {text!r}: nothing open here to close", token.start)
                    paired = False
                continue
            top = opened[-1]
            if _CLOSER[top.text] != text:
                if paired and _STRENGTH[text] > _STRENGTH[_CLOSER[top.text]]:
                    self._unclosed(top)  # `f(x }`: the '(' lost its ')'
                elif paired:
                    self.error(
                        f"{text!r} does not close the {top.text!r} at {self.where(top)}: "
                        f"expected {_CLOSER[top.text]!r}",
                        token.start,
                    )
                paired = False
            elif paired and text == "}" and self._dedented(top, token, opened):
                self._unclosed(top)
                paired = False
            opened.pop()
        self.error(
            "this block is not closed: expected ']' after its functions", found[open_index].start
        )
        return None, False

    def _unclosed(self, token: Token) -> None:
        self.error(f"{token.text!r} is not closed: expected {_CLOSER[token.text]!r}", token.start)

    def _indent(self, offset: int) -> int | None:
        """The indentation of the line at `offset`, if the token there starts the line."""
        line = self.text.position(offset)[0]
        start = self.text.line_starts[line - 1]
        blank = self.source[start:offset]
        return len(blank) if not blank.strip() else None

    def _line_indent(self, offset: int) -> int:
        line = self.text.position(offset)[0]
        start = self.text.line_starts[line - 1]
        text = self.source[start:offset]
        return len(text) - len(text.lstrip())

    def _dedented(self, top: Token, close: Token, opened: list[Token]) -> bool:
        """A '}' that starts its line at the indentation of an outer '{' line, not of the
        line of the '{' it pairs with: that one lost its own '}' (formatted code)."""
        indent = self._indent(close.start)
        if indent is None or indent == self._line_indent(top.start):
            return False
        return any(o.text == "{" and self._line_indent(o.start) == indent for o in opened[:-1])

    # -- functions ------------------------------------------------------------------------

    def items(self, block: list[Token], layer: LayerDecl | None) -> BlockItems:
        """The layer language's items inside a block, at its top level (outside braces): a
        description (a string literal first), `on activate { ... }` / `on deactivate { ... }`
        hooks and `when (CONDITION)` guards between a definition's declarator and body."""
        items = BlockItems()
        scan = _Scan(block, len(block) - 1, layer, items)  # end: at the closing ']'
        end = scan.end
        errors = len(self.sink.items)
        braces = parens = 0
        item_start = True  # at the start of an item (not inside a definition)
        declarator = False  # a definition's parameter list has closed
        k = 1
        while k < end:
            token = block[k]
            text = token.text
            if braces or parens:
                braces += {"{": 1, "}": -1}.get(text, 0)
                parens += {"(": 1, ")": -1}.get(text, 0) if not braces else 0
                if not braces and not parens:
                    item_start, declarator = text == "}", text == ")" or declarator
                    declarator = declarator and text != "}"
                k += 1
                continue
            if token.kind in _STRINGS and item_start:
                k = self._description(scan, k)
                continue
            if text == "on" and item_start and k + 1 < end and block[k + 1].text.isidentifier():
                k = self._hook(scan, k)
                continue
            if (
                item_start
                and text.isidentifier()
                and k + 2 < end
                and block[k + 1].text in ("activate", "deactivate")
                and block[k + 2].text == "{"
            ):  # `onx activate { ... }`
                event = block[k + 1].text
                self.error(f"expected 'on {event} {{ ... }}', found {text!r}", token.start)
                k += 2
                continue
            if text in ("activate", "deactivate") and item_start and block[k + 1].text == "{":
                self.error(
                    f"expected 'on' before {text!r}: a hook is 'on {text} {{ ... }}'", token.start
                )
                k += 1
                continue
            if text == "when" and declarator and k + 1 < end and block[k + 1].text == "(":
                k = self._guard(scan, k)
                continue
            braces += text == "{"
            parens += text == "("
            item_start = text == ";"
            k += 1
        items.broken = len(self.sink.items) > errors
        return items

    def _description(self, scan: _Scan, k: int) -> int:
        block, end, layer, items = scan.tokens, scan.end, scan.layer, scan.items
        start = k
        parts: list[str] = []
        while k < end and block[k].kind in _STRINGS:  # "a" "b": joined, as C++ does
            parts.append(block[k].text)
            k += 1
        stop = block[k - 1].end
        if k < end and block[k].text == ";":
            stop = block[k].end
            k += 1
        items.masks.append((block[start].start, stop))
        if layer is None or start != 1:
            self.error(
                "a description is a string literal first in a layer's block, not here in "
                + scan.where,
                block[start].start,
            )
            return k
        values: list[str] = []
        for part in parts:
            if not (part.startswith('"') and part.endswith('"') and len(part) >= 2):
                self.error(
                    'a layer\'s description is an ordinary string literal ("..."), '
                    f"found {part[:20]!r}",
                    block[start].start,
                )
                return k
            values.append(_unescape(part[1:-1]))
        layer.description = "".join(values)
        return k

    def _hook(self, scan: _Scan, k: int) -> int:
        block, end, layer = scan.tokens, scan.end, scan.layer
        on, event = block[k], block[k + 1]
        if event.text not in ("activate", "deactivate"):
            self.error(
                f"expected 'activate' or 'deactivate' after 'on', found {event.text!r}", event.start
            )
            return k + 2
        if k + 2 >= end or block[k + 2].text != "{":
            where_at = block[k + 2].start if k + 2 < end else event.end
            self.error(f"expected '{{' after 'on {event.text}': the hook's body", where_at)
            return k + 2
        close = scan.closing(k + 2)
        scan.items.masks.append((on.start, block[close].end))
        if layer is None:
            self.error(f"'on {event.text}' belongs to a layer: {scan.where} has no hooks", on.start)
            return close + 1
        layer.hooks.append(
            CppHook(
                event=event.text,
                layer=layer.name,
                at=self.at(on.start),
                lines=[],
                generated_name=f"on_{event.text}_{layer.name}",
                body_start=block[k + 2].start,
                body_end=block[close].end,
            )
        )
        return close + 1

    def _guard(self, scan: _Scan, k: int) -> int:
        block, end, items = scan.tokens, scan.end, scan.items
        close = scan.closing(k + 1)
        if close >= end:
            self.error("this guard's '(' is not closed", block[k + 1].start)
            return end
        if close == k + 2:
            self.error("expected a condition in 'when ( )'", block[k + 1].end)
        items.masks.append((block[k].start, block[close].end))
        condition = (block[k + 1].end, block[close].start)
        items.guards.append(GuardSpan(block[k].start, block[close].end, condition))
        return close + 1

    def functions(
        self, opening: Token, closing: Token, layer: str | None, items: BlockItems
    ) -> list[Function]:
        """The block's function definitions (none if its items were reported)."""
        owner_text = f"layer {layer}" if layer is not None else "the base block"
        text = self.text
        if items.masks:  # the layer language's items become blanks: C++ is left
            masked = self.source
            for a, b in items.masks:
                blank = "".join(c if c in "\r\n" else " " for c in masked[a:b])
                masked = masked[:a] + blank + masked[b:]
            text = SourceText(masked)
        functions = (
            []
            if items.broken
            else FunctionReader(text, self.source, self.sink).definitions(
                opening.end, closing.start, layer, owner_text, items.guards
            )
        )
        guards = [(g.when, g.close) for g in items.guards]
        hooks = any(m for m in items.masks if m not in guards)
        if not functions and not hooks and not self.sink.has_errors:
            self.error(
                f"{owner_text} is empty: expected function definitions between '[' and ']'",
                opening.start,
            )
        return functions


def _unescape(text: str) -> str:
    """The value of an ordinary C++ string literal's content (the simple escapes)."""
    out: list[str] = []
    i = 0
    while i < len(text):
        if text[i] == "\\" and i + 1 < len(text):
            out.append(_ESCAPES.get(text[i + 1], text[i + 1]))
            i += 2
            continue
        out.append(text[i])
        i += 1
    return "".join(out)
