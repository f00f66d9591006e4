"""The C++ flavour's parser: a header part of plain C++, then `Layer Name [ ... ]` blocks.

The layer language's own structure (declarations, relations, brackets) is read from
tree-sitter's tokens of the file, so brackets, strings and comments inside C++ never
confuse it; every block's content is parsed by tree-sitter's C++ grammar as function
definitions. The result is the language-neutral tree of syntax.py, with `CppFunction`s
carrying the text spans the back end rewrites (tree.py).

The parts, each in its module: the header part (header.py), a block's brackets and items
(blocks.py), function definitions (functions.py); here the declarations between them, and
the checks of the layers' functions against the header's declarations.
"""

from __future__ import annotations

from contextros.language.cpp.blocks import BlockReader
from contextros.language.cpp.header import HeaderReader
from contextros.language.cpp.names import (
    DECLARATION_WORDS,
    LAYER_WORDS,
    name_problem,
)
from contextros.language.cpp.reading import Reader
from contextros.language.cpp.tokens import SourceText, Token, tokens
from contextros.language.cpp.tree import CppFunction, CppLayerFile
from contextros.language.diagnostics import Diagnostic, DiagnosticSink
from contextros.language.syntax import BaseBlock, GroupDecl, LayerDecl, Ref
from contextros.language.words import RELATIONS, expected_declaration, relation_words


def parse_with_diagnostics(
    source: str, path: str = "<layers>"
) -> tuple[CppLayerFile, list[Diagnostic]]:
    """Parse as far as possible and return the tree with all diagnostics (never raises them)."""
    return _Parser(source, path).run()


class _Parser(Reader):
    def __init__(self, source: str, path: str) -> None:
        super().__init__(SourceText(source), source, DiagnosticSink(path, source, syntax=True))
        self.path = path
        self.header = HeaderReader(self.text, source, self.sink)
        self.blocks = BlockReader(self.text, source, self.sink)

    # -- file level ---------------------------------------------------------------------

    def run(self) -> tuple[CppLayerFile, list[Diagnostic]]:
        header_end = self.header.end()
        header_lines = (
            self.text.position(header_end)[0] - 1
            if header_end < len(self.source)
            else (
                len(self.text.line_starts)
                if self.source and not self.source.endswith(("\n", "\r"))
                else len(self.text.line_starts) - 1
            )
        )
        result = CppLayerFile(
            path=self.path,
            source=self.source,
            header=self.source[:header_end],
            header_lines=header_lines,
            language="cpp",
            header_end=header_end,
        )
        self.header.read(result)
        # `rule`, `parameter`, `lifecycle` and `topic` lines: the shared, neutral grammar;
        # then blanked out, so the C++ tokens of the rest keep their offsets.
        masked = self.header.line_declarations(header_end, result)
        text = self.text if masked == self.source else SourceText(masked)
        found, bad = tokens(text, header_end, len(self.source))
        if bad is not None:
            self.error(f"unexpected character {self.source[bad]!r}", bad)
        found = [t for t in found if t.kind != "comment"]
        self._declarations(found, result)
        self._parameter_names(result)
        self._class_declarations(result)
        return result, self.sink.items

    def _class_declarations(self, result: CppLayerFile) -> None:
        """A layer's method must match its declaration in a class of the header part.

        Checked for the first implementation of each method: the checker compares the
        others with that one (one mistake, one error).
        """
        seen: set[str] = set()
        for function in sorted(result.all_functions(), key=lambda f: (f.at.line, f.at.col)):
            if not isinstance(function, CppFunction) or function.key in seen:
                continue
            seen.add(function.key)
            if function.owner is None:
                lines = result.header_overloads.get(function.name)
                if lines:
                    self._overloaded(function, "the header part", lines)
                continue
            cls = result.class_named(function.owner)
            if cls is None and result.is_namespace(function.owner):
                self.sink.error(
                    f"cannot layer {function.key}: {function.owner} is a namespace, and a "
                    "layered free function lives at global scope (define it there, or make "
                    "it a method of a class)",
                    function.at.line,
                    function.at.col,
                )
                continue
            if cls is not None and function.name in cls.overloads:
                self._overloaded(function, f"class {function.owner}", cls.overloads[function.name])
                continue
            if cls is not None and function.name in cls.static_methods:
                self.sink.error(
                    f"cannot layer {function.key}: class {function.owner} declares it static "
                    "(only non-static member functions and free functions can be layered)",
                    function.at.line,
                    function.at.col,
                )
                continue
            declared = cls.declarations.get(function.name) if cls is not None else None
            if declared is None or declared.shape == function.signature.shape:
                continue
            self.sink.error(
                f"incompatible signature: {function.signature.text} does not match the "
                f"declaration {declared.text} in class {function.owner} (line {declared.line})",
                function.at.line,
                function.at.col,
            )

    def _overloaded(self, function: CppFunction, where: str, lines: tuple[int, ...]) -> None:
        listed = ", ".join(str(line) for line in lines)
        self.sink.error(
            f"cannot layer {function.key}: {where} declares {len(lines)} overloads of it (lines "
            f"{listed}), and a layered function is found by its name; give the one to layer its "
            f"own name ({function.name}_layered), layer that, and have the overload call it",
            function.at.line,
            function.at.col,
        )

    def _parameter_names(self, result: CppLayerFile) -> None:
        """The dispatch function forwards its arguments: it needs every parameter named."""
        by_key: dict[str, list[CppFunction]] = {}
        for function in result.all_functions():
            if isinstance(function, CppFunction):
                by_key.setdefault(function.key, []).append(function)
        for key, functions in by_key.items():
            if not any(None not in f.parameter_names for f in functions):
                first = functions[0]
                self.sink.error(
                    f"the dispatch function of {key} needs parameter names: name every "
                    "parameter in at least one implementation",
                    first.at.line,
                    first.at.col,
                )

    def _declarations(self, found: list[Token], result: CppLayerFile) -> None:
        i = 0
        while i < len(found):
            token = found[i]
            if token.text in LAYER_WORDS:
                i = self._layer(found, i, result)
            elif token.text == "group":
                i = self._group(found, i, result)
            elif token.text == "base":
                i = self._base(found, i, result)
            else:
                self.error(
                    f"{expected_declaration('Layer', token.text)}; C++ code belongs in the "
                    "header part, above the first declaration, or in a layer's [ ... ] block",
                    token.start,
                )
                i = self._recover(found, i + 1)

    def _recover(self, found: list[Token], i: int) -> int:
        """The next token that starts a line with a declaration word."""
        while i < len(found):
            token = found[i]
            col = self.text.position(token.start)[1]
            if col == 1 and token.text in DECLARATION_WORDS:
                return i
            i += 1
        return i

    def _name(self, found: list[Token], i: int, what: str, after: Token) -> Ref | None:
        if i < len(found) and found[i].text not in ("[", ":", ",", ";", "]"):
            token = found[i]
            problem = name_problem(token.text)
            if problem:
                self.error(f"{token.text!r} {problem}", token.start)
                return None
            return Ref(token.text, self.at(token.start))
        if i < len(found):
            self.error(f"expected {what}, found {found[i].text!r}", found[i].start)
        else:
            self.error(f"expected {what}", after.end)
        return None

    def _names(self, found: list[Token], i: int, what: str) -> tuple[list[Ref], int]:
        refs: list[Ref] = []
        while True:
            ref = self._name(found, i, what, found[i - 1])
            if ref is None:
                return refs, -1
            refs.append(ref)
            i += 1
            if i < len(found) and found[i].text == ",":
                i += 1
                continue
            return refs, i

    def _layer(self, found: list[Token], i: int, result: CppLayerFile) -> int:
        name = self._name(found, i + 1, "a layer name after 'Layer'", found[i])
        if name is None:
            return self._recover(found, i + 1)
        layer = LayerDecl(name.name, name.at)
        j = i + 2
        while j < len(found) and found[j].text in RELATIONS:
            relation = found[j].text
            refs, j = self._names(found, j + 1, f"a layer name after {relation!r}")
            if j < 0:
                return self._recover(found, i + 1)
            getattr(layer, relation).extend(refs)
        if j >= len(found) or found[j].text != "[":
            where = found[j].start if j < len(found) else found[j - 1].end
            got = f", found {found[j].text!r}" if j < len(found) else ""
            self.error(f"expected {relation_words('[')}{got}", where)
            return self._recover(found, j)
        result.layers.append(layer)  # declared, even if its block is broken
        close, paired = self.blocks.end(found, j)
        if close is None:
            return self._recover(found, j + 1)
        if paired:
            items = self.blocks.items(found[j : close + 1], layer)
            functions = self.blocks.functions(found[j], found[close], layer.name, items)
            layer.functions.extend(functions)
        return close + 1

    def _base(self, found: list[Token], i: int, result: CppLayerFile) -> int:
        j = i + 1
        if j >= len(found) or found[j].text != "[":
            self.error(
                "expected '[' after 'base'", found[j].start if j < len(found) else found[i].end
            )
            return self._recover(found, j)
        close, paired = self.blocks.end(found, j)
        if close is None:
            return self._recover(found, j + 1)
        block = BaseBlock(self.at(found[i].start))
        result.bases.append(block)
        if paired:
            items = self.blocks.items(found[j : close + 1], None)
            block.functions.extend(self.blocks.functions(found[j], found[close], None, items))
        return close + 1

    def _group(self, found: list[Token], i: int, result: CppLayerFile) -> int:
        name = self._name(found, i + 1, "a group name after 'group'", found[i])
        if name is None:
            return self._recover(found, i + 1)
        j = i + 2
        if j >= len(found) or found[j].text != ":":
            where = found[j].start if j < len(found) else found[j - 1].end
            self.error("expected ':' after the group name", where)
            return self._recover(found, j)
        members, j = self._names(found, j + 1, "a layer name in the group")
        if j < 0:
            return self._recover(found, i + 1)
        result.groups.append(GroupDecl(name.name, name.at, members))
        if j < len(found) and found[j].text == ";":
            return j + 1
        if j < len(found) and found[j].text not in DECLARATION_WORDS:
            self.error(
                f"expected ',' or ';' after a group member, found {found[j].text!r}", found[j].start
            )
            return self._recover(found, j)
        return j
