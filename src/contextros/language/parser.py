"""The structural parser of the layer language: a line-oriented, indentation-based reader.

The file is split into the Python header and the declarations (`layer`, `base`, `group`),
each declaration block into items (methods, hooks, a docstring), and every Python piece
is handed to Python's own parser with its `.layers` positions kept, so a syntax error in
a method body is reported at the right line and column of the layer file.
"""

from __future__ import annotations

import ast
import io
import keyword
import re
import tokenize
import unicodedata
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

from contextros.language.diagnostics import (
    Diagnostic,
    DiagnosticSink,
    LayerSyntaxError,
    source_lines,
)
from contextros.language.lines import is_line_declaration, parse_line_declaration
from contextros.language.python_syntax import (
    PythonFunction,
    guard_function_lines,
    header_names,
    python_function,
)
from contextros.language.syntax import (
    BaseBlock,
    GroupDecl,
    Guard,
    Hook,
    LayerDecl,
    LayerFile,
    Position,
    Ref,
    SourceLine,
    char_of_byte,
)
from contextros.language.words import (
    RELATIONS,
    a_declaration,
    expected_declaration,
    misspelt,
    relation_words,
)

# Maps a (1-based row, 0-based column) of a parsed piece to the same in the .layers file.
_Where = Callable[[int, int], tuple[int, int]]

HOOK_EVENTS = ("activate", "deactivate")

_NAME = r"[^\W\d]\w*"
# A column-0 line that starts a declaration (and cannot be Python: `layer X`, `base:`);
# `rule`, `parameter`, `lifecycle` and `topic` lines are detected as in every flavour (lines.py).
_DECLARATION_START = re.compile(rf"(?:(layer|group)[ \t]+({_NAME})|(base)[ \t]*:)")
_MISSPELT_START = re.compile(
    rf"({_NAME})(?:[ \t]+({_NAME})[ \t]*(?::|$|[ \t]+{_NAME})|[ \t]*:[ \t]*(?:#.*)?$)"
)
# Python's soft keywords: `case x:` is Python, not a misspelt `base`.
_SOFT_KEYWORDS = frozenset({"match", "case", "type", "_"})
# Keywords that may follow a name in a Python expression statement.
_OPERATOR_WORDS = frozenset({"and", "or", "is", "in", "not", "if", "else", "for", "async"})
_DECLARATION_WORD = re.compile(r"(layer|base|group|rule|parameter|lifecycle|topic)\b")
_BASE_LINE = re.compile(r"base[ \t]*:[ \t]*(?:#.*)?$")
_DEF = re.compile(
    rf"(?P<indent>[ \t]*)(?:async[ \t]+)?def[ \t]+"
    rf"(?P<target>(?:(?P<owner>{_NAME})[ \t]*\.[ \t]*)?(?P<name>{_NAME}))"
)
_HOOK = re.compile(r"(?P<indent>[ \t]*)on\b[ \t]*(?P<event>\w*)[ \t]*(?P<colon>:?)")
_TOKEN = re.compile(rf"(?P<ws>[ \t]+)|(?P<comment>#.*)|(?P<name>{_NAME})|(?P<punct>[:,])")


def parse(source: str, path: str = "<layers>") -> LayerFile:
    """Parse a layer file; raise `LayerSyntaxError` carrying every syntax error found."""
    layer_file, diagnostics = parse_with_diagnostics(source, path)
    errors = [d for d in diagnostics if d.is_error]
    if errors:
        raise LayerSyntaxError(errors)
    return layer_file


def parse_with_diagnostics(
    source: str, path: str = "<layers>"
) -> tuple[LayerFile, list[Diagnostic]]:
    """Parse as far as possible and return the tree with all diagnostics (never raises them)."""
    return _Parser(source, path).run()


def name_problem(name: str) -> str:
    """Why `name` cannot name a layer or a group in generated Python ('' if it can)."""
    if not name.isidentifier():
        return "is not a Python identifier"
    if unicodedata.normalize("NFKC", name) != name:
        return "is not in the normal form Python uses for identifiers (NFKC)"
    if name == "__debug__":
        return "cannot be assigned in Python"
    return ""


@dataclass(frozen=True)
class _Token:
    kind: str
    text: str
    col: int  # 0-based


def _indent_width(text: str) -> int:
    return len(text) - len(text.lstrip(" \t"))


def _is_blank(text: str) -> bool:
    stripped = text.strip()
    return not stripped or stripped.startswith("#")


def _open_in(lines: list[str]) -> str:
    """What the text ends inside: "string", "brackets" or "" (complete)."""
    text = "\n".join(lines) + "\n"
    try:
        for _ in tokenize.generate_tokens(io.StringIO(text).readline):
            pass
    except tokenize.TokenError as error:
        return "string" if "string" in str(error.args[0]) else "brackets"
    except (SyntaxError, ValueError):
        return ""
    return ""


def _is_open(lines: list[str]) -> bool:
    """True when the text ends inside a string or brackets, so its next line continues it."""
    return bool(_open_in(lines))


def _starts_declaration(text: str) -> bool:
    if is_line_declaration(text):
        return True
    match = _DECLARATION_START.match(text)
    if match is not None:
        return match.group(2) not in _OPERATOR_WORDS
    return _misspelt_declaration(text)


def _misspelt_declaration(text: str) -> bool:
    """`layr Indoor:`, `grou g: A, B`, `bas:`: a declaration with its word misspelt (no
    Python statement reads so: two names in a row, or a name and a lone ':')."""
    match = _MISSPELT_START.match(text)
    if match is None or match.group(1) in _SOFT_KEYWORDS:
        return False
    meant = misspelt(match.group(1), ("layer", "group", "base"))
    if meant == "base":
        return match.group(2) is None
    return bool(meant) and match.group(2) is not None


def _indented_declaration(text: str) -> bool:
    """An indented line that can only be a declaration (`layer X`, `group g`, a lone
    `base:`): never Python, so it ends the block above it instead of joining it."""
    if not text or text[0] not in " \t":
        return False
    stripped = text.lstrip(" \t")
    if _BASE_LINE.match(stripped) or is_line_declaration(stripped):
        return True
    match = _DECLARATION_START.match(stripped)
    if match is None or match.group(1) is None:
        return False
    return match.group(2) not in _OPERATOR_WORDS


def _lines_inside_strings(lines: list[str]) -> set[int]:
    """0-based indices of lines that begin inside a multi-line string: never re-indent them."""
    inside: set[int] = set()
    text = "\n".join(lines) + "\n"
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type in (tokenize.NEWLINE, tokenize.NL, tokenize.DEDENT, tokenize.INDENT):
                continue
            inside.update(range(tok.start[0], tok.end[0]))  # rows are 1-based: next rows
    except (tokenize.TokenError, SyntaxError, ValueError):
        pass
    return inside


class _Parser:
    def __init__(self, source: str, path: str) -> None:
        self.source = source
        self.path = path
        self.sink = DiagnosticSink(path, source, syntax=True)
        self.lines = source_lines(source)

    # -- file level ---------------------------------------------------------------------

    def run(self) -> tuple[LayerFile, list[Diagnostic]]:
        start = self._header_end()
        header = "\n".join(self.lines[:start])
        names, star = header_names(self._parse_header(header))
        result = LayerFile(
            path=self.path,
            source=self.source,
            header=header,
            header_lines=start,
            language="python",
            header_names=frozenset(names),
            header_opaque=star,
        )
        i = start
        while i < len(self.lines):
            text = self.lines[i]
            if _is_blank(text):
                i += 1
                continue
            if _indented_declaration(text):
                # One mistake, one error: say it, then read the declaration as meant.
                word = text.lstrip(" \t").split()[0].rstrip(":")
                self.sink.error(
                    f"unexpected indentation: '{word}' must start at the beginning of the "
                    "line (declarations are not indented)",
                    i + 1,
                    1,
                )
                end = self._block_end(i)
                self.lines[i] = text.lstrip(" \t")
                self._declaration(i, end, result)
                self.lines[i] = text
                i = end
                continue
            if text[0] in " \t":
                self.sink.error(
                    f"unexpected indentation: expected {a_declaration('layer')} at the start "
                    "of the line",
                    i + 1,
                    _indent_width(text) + 1,
                )
                i = self._block_end(i)
                continue
            end = self._block_end(i)
            self._declaration(i, end, result)
            i = end
        return result, self.sink.items

    def _header_end(self) -> int:
        """Index of the first declaration line: the header is everything before it."""
        for i, text in enumerate(self.lines):
            # Only a string may hold a declaration-like line; unclosed brackets before it
            # are an error of the header, reported as such.
            if _starts_declaration(text) and _open_in(self.lines[:i]) != "string":
                return i
            if _indented_declaration(text) and not _open_in(self.lines[:i]):
                return i  # misplaced, reported as such by run()
        return len(self.lines)

    def _parse_header(self, header: str) -> ast.Module | None:
        node = self._python(header, lambda row, col: (row, col), 1)
        return node if isinstance(node, ast.Module) else None

    def _block_end(self, start: int) -> int:
        """Index after the lines indented under line `start` (strings may reach column 0)."""
        j = start + 1
        while j < len(self.lines):
            text = self.lines[j]
            if _indented_declaration(text) and not _open_in(self.lines[start + 1 : j]):
                break
            if not text.strip() or text[0] in " \t#":
                j += 1
                continue
            state = _open_in(self.lines[start + 1 : j])
            if state == "string" or (state == "brackets" and not _starts_declaration(text)):
                j += 1
                continue
            break
        # Trailing blank and column-0 comment lines belong to no block.
        while j > start + 1 and (not self.lines[j - 1].strip() or self.lines[j - 1][0] == "#"):
            j -= 1
        return j

    # -- declaration lines --------------------------------------------------------------

    def _tokens(self, row: int, *, stop_at_colon: bool) -> list[_Token] | None:
        """The words of a declaration line; with `stop_at_colon`, the rest is one token."""
        text = self.lines[row]
        tokens: list[_Token] = []
        pos = 0
        while pos < len(text):
            if stop_at_colon and tokens and tokens[-1].text == ":":
                rest = text[pos:].strip()
                if rest and not rest.startswith("#"):
                    tokens.append(_Token("rest", rest, len(text) - len(text[pos:].lstrip())))
                break
            match = _TOKEN.match(text, pos)
            if match is None:
                self.sink.error(f"unexpected character {text[pos]!r}", row + 1, pos + 1)
                return None
            kind = match.lastgroup or ""
            if kind not in ("ws", "comment"):
                tokens.append(_Token(kind, match.group(), pos))
            pos = match.end()
        return tokens

    def _declaration(self, start: int, end: int, result: LayerFile) -> None:
        word = _DECLARATION_WORD.match(self.lines[start])
        if word is None:
            found = re.split(r"[\s:]", self.lines[start], maxsplit=1)[0] or self.lines[start]
            self.sink.error(
                f"{expected_declaration('layer', found)}; "
                "Python code belongs in the header, above the first declaration",
                start + 1,
                1,
            )
            return
        if word.group() in ("rule", "parameter", "lifecycle", "topic"):
            self._line_declaration(start, end, result)
            return
        tokens = self._tokens(start, stop_at_colon=word.group() != "group")
        if tokens is None:
            return
        first = tokens[0] if tokens else None
        if first is not None and first.text == "layer":
            known_errors = len(self.sink.items)
            layer = self._layer_line(start, tokens)
            if layer is not None:
                result.layers.append(layer)
                # An empty block after a broken line is that line's mistake, not another.
                line_ok = len(self.sink.items) == known_errors
                self._block(start, end, layer, None, report_empty=line_ok)
            return
        if first is not None and first.text == "base":
            if len(tokens) < 2 or tokens[1].text != ":" or len(tokens) > 2:
                col = tokens[1].col if len(tokens) > 1 else len(self.lines[start].rstrip())
                self.sink.error("expected 'base:' on a line of its own", start + 1, col + 1)
                return
            block = BaseBlock(Position(start + 1, 1))
            result.bases.append(block)
            self._block(start, end, None, block)
            return
        if first is not None and first.text == "group":
            group = self._group_line(start, tokens)
            if group is not None:
                result.groups.append(group)
            if end > start + 1:
                row = next(r for r in range(start + 1, end) if not _is_blank(self.lines[r]))
                self.sink.error(
                    "unexpected indentation: a group is declared on one line",
                    row + 1,
                    _indent_width(self.lines[row]) + 1,
                )
            return
        found = first.text if first is not None else self.lines[start].strip()
        self.sink.error(
            f"{expected_declaration('layer', found)}; "
            "Python code belongs in the header, above the first declaration",
            start + 1,
            1,
        )

    def _expect_name(self, row: int, tokens: list[_Token], i: int, what: str) -> Ref | None:
        if i < len(tokens) and tokens[i].kind == "name" and not keyword.iskeyword(tokens[i].text):
            name = tokens[i].text
            at = Position(row + 1, tokens[i].col + 1)
            problem = name_problem(name)
            if problem:
                self.sink.error(f"{name!r} {problem}", at.line, at.col)
                return None
            return Ref(name, at)
        col = tokens[i].col if i < len(tokens) else len(self.lines[row].split("#")[0].rstrip())
        found = f", found {tokens[i].text!r}" if i < len(tokens) else ""
        self.sink.error(f"expected {what}{found}", row + 1, col + 1)
        return None

    def _name_list(
        self, row: int, tokens: list[_Token], i: int, what: str
    ) -> tuple[list[Ref], int]:
        names: list[Ref] = []
        while True:
            ref = self._expect_name(row, tokens, i, what)
            if ref is None:
                return names, -1
            names.append(ref)
            i += 1
            if i < len(tokens) and tokens[i].text == ",":
                i += 1
                continue
            return names, i

    def _layer_line(self, row: int, tokens: list[_Token]) -> LayerDecl | None:
        name = self._expect_name(row, tokens, 1, "a layer name after 'layer'")
        if name is None:
            return None
        # From here on the layer is declared even when the rest of its line is wrong, so
        # that the file's other mentions of it are not reported as follow-on errors.
        layer = LayerDecl(name.name, name.at)
        i = 2
        while i < len(tokens) and tokens[i].text in RELATIONS:
            relation = tokens[i].text
            refs, i = self._name_list(row, tokens, i + 1, f"a layer name after {relation!r}")
            getattr(layer, relation).extend(refs)
            if i < 0:
                return layer
        end_col = len(self.lines[row].split("#")[0].rstrip())
        if i >= len(tokens):
            self.sink.error(
                "expected ':' at the end of the layer declaration", row + 1, end_col + 1
            )
        elif tokens[i].text != ":":
            self.sink.error(
                f"expected {relation_words(':')}, found {tokens[i].text!r}",
                row + 1,
                tokens[i].col + 1,
            )
        elif i + 1 < len(tokens):
            self.sink.error(
                "a layer's methods start on the next line, indented",
                row + 1,
                tokens[i + 1].col + 1,
            )
        return layer

    def _line_declaration(self, start: int, end: int, result: LayerFile) -> None:
        """`rule NAME: ...`, `parameter LAYER: ...`, `lifecycle LAYER: ...`, `topic NAME: ...`
        on one line; a language-neutral grammar shared with the C++ flavour (lines.py)."""
        text = self.lines[start]
        word = text.split()[0] if text.split() else "rule"
        parse_line_declaration(text, start + 1, result, self.sink)
        if end > start + 1:
            row = next(r for r in range(start + 1, end) if not _is_blank(self.lines[r]))
            self.sink.error(
                f"unexpected indentation: a {word} is declared on one line",
                row + 1,
                _indent_width(self.lines[row]) + 1,
            )

    def _group_line(self, row: int, tokens: list[_Token]) -> GroupDecl | None:
        name = self._expect_name(row, tokens, 1, "a group name after 'group'")
        if name is None:
            return None
        if len(tokens) < 3 or tokens[2].text != ":":
            col = tokens[2].col if len(tokens) > 2 else len(self.lines[row].split("#")[0].rstrip())
            self.sink.error("expected ':' after the group name", row + 1, col + 1)
            return None
        members, i = self._name_list(row, tokens, 3, "a layer name in the group")
        if i < 0:
            return GroupDecl(name.name, name.at, members)
        if i < len(tokens):
            self.sink.error(
                f"expected ',' between group members, found {tokens[i].text!r}",
                row + 1,
                tokens[i].col + 1,
            )
            return None
        return GroupDecl(name.name, name.at, members)

    # -- blocks and their items ---------------------------------------------------------

    def _items(self, start: int, end: int) -> Iterator[tuple[int, int]]:
        """Split the block under line `start` into items: (first row, end row)."""
        rows = [r for r in range(start + 1, end) if not _is_blank(self.lines[r])]
        if not rows:
            return
        indent = _indent_width(self.lines[rows[0]])
        item_start = rows[0]
        decorators_only = self.lines[rows[0]].lstrip().startswith("@")
        for row in rows[1:]:
            width = _indent_width(self.lines[row])
            if width > indent or _is_open(self.lines[item_start:row]):
                decorators_only = False
                continue
            if decorators_only:  # `@decorator` lines belong to the `def` below them
                decorators_only = self.lines[row].lstrip().startswith("@")
                continue
            if width < indent:
                self.sink.error(
                    "unindent does not match the indentation of the block's other items",
                    row + 1,
                    width + 1,
                )
            yield item_start, row
            item_start = row
            decorators_only = self.lines[row].lstrip().startswith("@")
        yield item_start, end

    def _block(
        self,
        start: int,
        end: int,
        layer: LayerDecl | None,
        base: BaseBlock | None,
        *,
        report_empty: bool = True,
    ) -> None:
        owner = f"layer {layer.name}" if layer is not None else "the base block"
        first_item = True
        found_any = False
        for item_start, item_end in self._items(start, end):
            found_any = True
            stripped = self.lines[item_start].lstrip()
            col = _indent_width(self.lines[item_start]) + 1
            if stripped.startswith(("@", "def", "async")):
                function = self._function(item_start, item_end, layer)
                if function is not None:
                    (layer.functions if layer is not None else base.functions).append(  # type: ignore[union-attr]
                        function
                    )
            elif re.match(r"on\b", stripped):
                if layer is None:
                    self.sink.error(
                        "activation hooks belong to a layer, not to the base block",
                        item_start + 1,
                        col,
                    )
                else:
                    hook = self._hook(item_start, item_end, layer)
                    if hook is not None:
                        layer.hooks.append(hook)
            elif first_item and re.match(r"[rRuUbBfF]{0,2}['\"]", stripped):
                description = self._docstring(item_start, item_end)
                if description is not None and layer is not None:
                    layer.description = description
            else:
                self.sink.error(
                    f"expected a method ('def name(...):' or 'def Class.name(...):')"
                    f"{', a hook (on activate:)' if layer is not None else ''} in {owner}",
                    item_start + 1,
                    col,
                )
            first_item = False
        if not found_any and report_empty:
            text = self.lines[start].split("#")[0].rstrip()
            self.sink.error(
                f"{owner} is empty: expected indented methods below it", start + 1, len(text) + 1
            )

    def _dedent(self, first: int, end: int) -> list[SourceLine]:
        rows = list(range(first, end))
        while rows and not self.lines[rows[-1]].strip():
            rows.pop()
        indent = _indent_width(self.lines[first])
        raw = [self.lines[r] for r in rows]
        inside = _lines_inside_strings(raw)
        result: list[SourceLine] = []
        for k, (row, text) in enumerate(zip(rows, raw, strict=True)):
            cut = 0 if k in inside else min(indent, _indent_width(text))
            result.append(SourceLine(text[cut:], row + 1, cut))
        return result

    def _rename(self, line: SourceLine, start: int, end: int, new: str) -> SourceLine:
        """Replace text[start:end] of a dedented line by `new`, keeping columns mappable.

        Python's AST counts columns in UTF-8 bytes, its parser's errors in characters: the
        shift after the new name is kept in both.
        """
        text = line.text[:start] + new + line.text[end:]
        old_width = len(line.text[start:end].encode())
        split = len(text[: start + len(new)].encode())
        return SourceLine(
            text,
            line.line,
            line.delta,
            split,
            old_width - len(new.encode()) + line.delta,
            start + len(new),
            (end - start) - len(new) + line.delta,
        )

    def _function(self, first: int, end: int, layer: LayerDecl | None) -> PythonFunction | None:
        lines = self._dedent(first, end)
        def_index = next(
            (k for k, ln in enumerate(lines) if not ln.text.lstrip().startswith(("@", "#"))),
            0,
        )
        match = _DEF.match(lines[def_index].text)
        owner = name = None
        at = Position(lines[def_index].line, lines[0].delta + 1)
        generated = ""
        if match is not None:
            owner, name = match.group("owner"), match.group("name")
            at = Position(lines[def_index].line, lines[def_index].delta + match.start("target") + 1)
            stem = f"{owner}_{name}" if owner else name
            generated = f"{stem}_{layer.name}" if layer is not None else stem
            lines[def_index] = self._rename(
                lines[def_index], match.start("target"), match.end("target"), generated
            )
        guard: _CutGuard | None = None
        if match is not None:
            guard = self._cut_guard(lines, def_index)
            if guard is not None and guard.problem:
                return None
        node = self._python_lines(lines)
        if node is None or match is None or name is None:
            if node is not None:  # Python accepted it, yet it is not `def name(...)`
                self.sink.error("expected a method definition", at.line, at.col)
            return None
        for part in (owner, name):
            problem = name_problem(part) if part else ""
            if problem:
                self.sink.error(f"{part!r} {problem}", at.line, at.col)
                return None
        if len(node.body) != 1 or not isinstance(
            node.body[0], (ast.FunctionDef, ast.AsyncFunctionDef)
        ):
            self.sink.error("expected a single method definition", at.line, at.col)
            return None
        function_node = node.body[0]
        if guard is not None and not self._guard_compiles(guard, function_node):
            return None
        return python_function(
            name=name,
            owner=owner,
            layer=layer.name if layer is not None else None,
            at=at,
            node=function_node,
            lines=lines,
            generated_name=generated,
            guard=guard.guard if guard is not None else None,
            guard_lines=guard.lines if guard is not None else (),
        )

    def _cut_guard(self, lines: list[SourceLine], def_index: int) -> _CutGuard | None:
        """Find `when CONDITION` between a def's parameter list and its header's `:`, and
        blank it out of `lines` (column for column), for Python to parse the rest.

        The condition is kept as its own pieces of lines, each with its file position."""
        rows = lines[def_index:]
        text = "\n".join(line.text for line in rows) + "\n"
        depth, after_parameters, previous = 0, False, ""
        start: tuple[int, int] | None = None
        end: tuple[int, int] | None = None
        bare_lambda: tuple[int, int] | None = None
        try:
            for token in tokenize.generate_tokens(io.StringIO(text).readline):
                if token.type == tokenize.OP:
                    if token.string in "([{":
                        depth += 1
                    elif token.string in ")]}":
                        depth -= 1
                        after_parameters = after_parameters or depth == 0
                    elif token.string == ":" and depth == 0 and after_parameters:
                        end = token.start
                        break
                elif (
                    token.type == tokenize.NAME
                    and token.string == "when"
                    and depth == 0
                    and after_parameters
                    and start is None
                    and previous != "->"
                ):
                    start = token.start
                elif token.type == tokenize.NAME and token.string == "lambda" and depth == 0:
                    bare_lambda = bare_lambda or token.start
                elif token.type in (tokenize.NEWLINE, tokenize.ENDMARKER):
                    break
                previous = token.string
        except (tokenize.TokenError, SyntaxError):
            return None  # Python's parser reports the header's own problem
        if start is None:
            return None
        first = rows[start[0] - 1]
        when_at = Position(first.line, first.char_column(start[1]) + 1)
        if bare_lambda is not None and bare_lambda > start:
            line = rows[bare_lambda[0] - 1]
            self.sink.error(
                "a lambda in a guard needs parentheses: its ':' would end the 'def' line",
                line.line,
                line.char_column(bare_lambda[1]) + 1,
            )
            return _CutGuard(None, (), problem=True)
        if end is None:
            self.sink.error(
                "expected ':' after the guard ('when CONDITION:')", when_at.line, when_at.col
            )
            return _CutGuard(None, (), problem=True)
        pieces: list[SourceLine] = []
        condition_start: Position | None = None
        for row in range(start[0], end[0] + 1):
            line = rows[row - 1]
            begin = start[1] + len("when") if row == start[0] else 0
            stop = end[1] if row == end[0] else len(line.text)
            piece = line.text[begin:stop]
            if piece.strip() and condition_start is None:
                column = begin + len(piece) - len(piece.lstrip())
                condition_start = Position(line.line, line.char_column(column) + 1)
            byte_begin = len(line.text[:begin].encode())
            pieces.append(SourceLine(piece, line.line, line.column(byte_begin)))
            cut_from = start[1] if row == start[0] else 0
            blank = " " * (stop - cut_from)
            if row != end[0]:  # the header goes on below: keep the lines joined
                blank = blank[:-1] + "\\" if blank else "\\"
            rows[row - 1] = replace(line, text=line.text[:cut_from] + blank + line.text[stop:])
        rest = rows[end[0] - 1].text[end[1] + 1 :]
        if not rest.strip() or rest.lstrip().startswith("#"):
            # Nothing but the header's `:` after the guard (the usual case): the header
            # ends where the guard started, the guard's other lines stay as empty lines.
            for row in range(start[0], end[0] + 1):
                line = rows[row - 1]
                kept = line.text[: start[1]].rstrip() + ":" if row == start[0] else ""
                rows[row - 1] = replace(line, text=kept + (rest if row == end[0] else ""))
        lines[def_index:] = rows
        condition = "\n".join(p.text for p in pieces).strip()
        if not condition or condition_start is None:
            self.sink.error("expected a condition after 'when'", when_at.line, when_at.col)
            return _CutGuard(None, (), problem=True)
        return _CutGuard(Guard(condition, condition_start), tuple(pieces))

    def _guard_compiles(
        self, guard: _CutGuard, function: ast.FunctionDef | ast.AsyncFunctionDef
    ) -> bool:
        """Python's parser and compiler on the guard, as the back end will emit it: a plain
        function of the implementation's parameters returning the condition."""
        assert guard.guard is not None
        at = guard.guard.at
        lines = guard_function_lines(guard.lines, function, "guard")

        def where(row: int, col: int) -> tuple[int, int]:
            line = lines[min(max(row, 1), len(lines)) - 1]
            if isinstance(line, SourceLine):
                return line.line, line.char_column(col)
            return at.line, at.col - 1  # the generated `def` line: the condition

        text = "\n".join(ln.text if isinstance(ln, SourceLine) else ln for ln in lines) + "\n"
        before = len(self.sink.items)
        self._python(text, where, at.line)
        return not any(d.is_error for d in self.sink.items[before:])

    def _hook(self, first: int, end: int, layer: LayerDecl) -> Hook | None:
        lines = self._dedent(first, end)
        match = _HOOK.match(lines[0].text)
        col = lines[0].delta + 1
        if match is None or match.group("event") not in HOOK_EVENTS:
            self.sink.error("expected 'on activate:' or 'on deactivate:'", first + 1, col)
            return None
        if not match.group("colon"):
            self.sink.error(
                f"expected ':' after 'on {match.group('event')}'",
                first + 1,
                lines[0].delta + match.end() + 1,
            )
            return None
        event = match.group("event")
        generated = f"on_{event}_{layer.name}"
        lines[0] = self._rename(lines[0], 0, match.end(), f"def {generated}():")
        node = self._python_lines(lines)
        if node is None:
            return None
        return Hook(event, layer.name, Position(first + 1, col), lines, generated)

    def _docstring(self, first: int, end: int) -> str | None:
        lines = self._dedent(first, end)
        node = self._python_lines(lines)
        if node is None:
            return None
        body = node.body
        if (
            len(body) != 1
            or not isinstance(body[0], ast.Expr)
            or not isinstance(body[0].value, ast.Constant)
            or not isinstance(body[0].value.value, str)
        ):
            self.sink.error(
                "expected a docstring, a method or a hook", first + 1, lines[0].delta + 1
            )
            return None
        return body[0].value.value

    # -- Python pieces --------------------------------------------------------------------

    def _python_lines(self, lines: list[SourceLine]) -> ast.Module | None:
        def where(row: int, col: int) -> tuple[int, int]:
            line = lines[min(max(row, 1), len(lines)) - 1]
            return line.line, line.char_column(col)

        return self._python("\n".join(ln.text for ln in lines) + "\n", where, lines[0].line)

    def _python(self, text: str, where: _Where, fallback_line: int) -> ast.Module | None:
        """Python's own parser on a piece of the file; its findings mapped back to the file.

        The piece is parsed under a name that is not a file: given a real path, CPython
        re-reads the error's line from disk and computes the column against the wrong text.
        """
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                node = ast.parse(text, filename="<layer piece>")  # not the real file: see below
            except SyntaxError as error:
                row, col = where(error.lineno or fallback_line, _error_column(error, text))
                self.sink.error(f"Python syntax error: {error.msg}", row, col + 1)
                return None
            except (ValueError, RecursionError, MemoryError) as error:
                self.sink.error(f"Python cannot parse this: {error}", fallback_line, 1)
                return None
            try:
                # Errors only the compiler finds: `return` outside a function, misplaced
                # `nonlocal`, `await` outside `async def`...
                compile(node, "<layer piece>", "exec", dont_inherit=True)
            except SyntaxError as error:
                # The compiler's offsets count UTF-8 bytes (its parser's count characters).
                lineno = error.lineno or fallback_line
                pieces = text.split("\n")
                piece = pieces[lineno - 1] if 1 <= lineno <= len(pieces) else ""
                row, col = where(lineno, char_of_byte(piece, (error.offset or 1) - 1))
                self.sink.error(f"Python syntax error: {error.msg}", row, col + 1)
                return None
            except (ValueError, RecursionError, MemoryError) as error:
                self.sink.error(f"Python cannot compile this: {error}", fallback_line, 1)
                return None
        for warning in caught:
            if issubclass(warning.category, (SyntaxWarning, DeprecationWarning)):
                row, col = where(warning.lineno or fallback_line, 0)
                self.sink.warning(f"Python: {warning.message}", row, col + 1)
        return node


@dataclass(frozen=True)
class _CutGuard:
    guard: Guard | None
    lines: tuple[SourceLine, ...]
    problem: bool = False


def _error_column(error: SyntaxError, text: str) -> int:
    """0-based column of a Python syntax error in `text`: for an indentation error, where
    the line's code starts (Python points past the line's end for an unindent)."""
    if isinstance(error, IndentationError) and error.lineno:
        lines = text.split("\n")
        if 1 <= error.lineno <= len(lines):
            line = lines[error.lineno - 1]
            if line.strip():
                return _indent_width(line)
    return max((error.offset or 1) - 1, 0)
