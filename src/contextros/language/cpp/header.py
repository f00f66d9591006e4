"""The header part of a C++ layer file: where it ends (the first declaration), the
`rule`/`parameter`/`lifecycle`/`topic` lines after it, and what it declares (classes and
their methods, functions, names, namespaces), which the layers' functions are checked
against and the generated code extends."""

from __future__ import annotations

import tree_sitter

from contextros.language.cpp.functions import FunctionReader, function_declarator
from contextros.language.cpp.names import DECLARATION_WORDS, misspelt_declaration
from contextros.language.cpp.reading import Reader
from contextros.language.cpp.tokens import identifier_char, leaves
from contextros.language.cpp.tree import CppClass, CppLayerFile, DeclaredMethod
from contextros.language.lines import is_line_declaration, parse_line_declaration


class HeaderReader(Reader):
    @property
    def functions(self) -> FunctionReader:
        """Reads the header's function declarations as the layers' definitions are read."""
        return FunctionReader(self.text, self.source, self.sink)

    def end(self) -> int:
        """Where the first declaration starts: a column-1 `Layer X`, `group X:`, `base [` or a
        `rule`/`parameter`/`lifecycle`/`topic` line."""
        tree: tree_sitter.Tree | None = None
        for start in self.text.line_starts:
            if not self._declaration_line(start):
                continue
            tree = tree or self.text.parse()
            node = tree.root_node.descendant_for_byte_range(
                self.text.byte(start), self.text.byte(start) + 1
            )
            inside = False
            while node is not None:
                if node.type in ("comment", "string_literal", "raw_string_literal") or (
                    node.type.startswith("preproc_")
                    and node.type != "preproc_include"
                    and self.text.char(node.start_byte) < start
                    and node.type
                    not in ("preproc_if", "preproc_ifdef", "preproc_else", "preproc_elif")
                ):
                    inside = True
                    break
                node = node.parent
            if not inside:
                return start
        return len(self.source)

    def _word(self, offset: int) -> tuple[str, int]:
        end = offset
        while end < len(self.source) and identifier_char(self.source[end]):
            end += 1
        return self.source[offset:end], end

    def _skip_blanks(self, offset: int) -> int:
        while offset < len(self.source) and self.source[offset] in " \t":
            offset += 1
        return offset

    def line_declarations(self, header_end: int, result: CppLayerFile) -> str:
        """Hand every column-1 `rule`/`parameter`/`lifecycle`/`topic` line to the shared parser
        (without its `//` comment and an optional `;`); return the source with those lines
        blanked."""
        masked = self.source
        for number, start in enumerate(self.text.line_starts, start=1):
            if start < header_end or not is_line_declaration(self.source, start):
                continue
            end = start
            while end < len(self.source) and self.source[end] not in "\r\n":
                end += 1
            line = self.source[start:end]
            code = line.split("//", 1)[0].rstrip()
            code = code[:-1].rstrip() if code.endswith(";") else code
            parse_line_declaration(code, number, result, self.sink)
            masked = masked[:start] + " " * (end - start) + masked[end:]
        return masked

    def _declaration_line(self, start: int) -> bool:
        if is_line_declaration(self.source, start):
            return True
        word, end = self._word(start)
        if end == start:
            return False
        misspelt = word not in DECLARATION_WORDS and misspelt_declaration(word)
        if word not in DECLARATION_WORDS and not misspelt:
            return False
        after = self._skip_blanks(end)
        if word == "base" or misspelt == "base":
            return after < len(self.source) and self.source[after] == "["
        if after == end:
            return False
        name, name_end = self._word(after)
        if not name:
            return False
        rest = self._skip_blanks(name_end)
        following = self.source[rest] if rest < len(self.source) else ""
        if misspelt:  # `grou g: A, B`, `Layr A [`: no C++ declaration reads so
            return following in (":", "[")
        if word == "group":
            # `group g: A, B;`, and with its ':' lost (`group g A, B;`, `group g; A, B;`)
            line_end = self.source.find("\n", rest)
            more = self.source[rest + 1 : None if line_end < 0 else line_end].split("//")[0]
            return (
                following == ":"
                or identifier_char(following)
                or (following == ";" and bool(more.strip()))
            )
        # `Layer x;`, `Layer x = ...`, `Layer f(...)` are C++ in the header; a layer line
        # goes on with a relation (or a misspelt one), '[' or nothing.
        return following in ("[", "\n", "\r", "") or identifier_char(following)

    # -- the header part ----------------------------------------------------------------

    def read(self, result: CppLayerFile) -> None:
        """What the header part (`result.header`) declares, into `result`."""
        if not result.header.strip():
            return
        tree = self.text.parse(0, result.header_end)
        names: set[str] = set()
        functions: set[str] = set()
        declared: dict[str, dict[tuple[str, ...], int]] = {}  # name: parameter types: line
        namespaces: set[str] = set()
        opaque = False
        pending: list[tuple[tree_sitter.Node, str]] = [(tree.root_node, "")]
        while pending:
            node, scope = pending.pop()
            for child in node.named_children:
                kind = child.type
                if kind in ("preproc_include", "using_declaration"):
                    opaque = True
                elif kind == "namespace_definition":
                    name = child.child_by_field_name("name")
                    body = child.child_by_field_name("body")
                    if body is not None:
                        nested = f"{scope}{self.text.text(name)}::" if name is not None else scope
                        if nested != scope:
                            namespaces.add(nested.removesuffix("::"))
                        pending.append((body, nested))
                elif kind in (
                    "preproc_if",
                    "preproc_ifdef",
                    "preproc_else",
                    "preproc_elif",
                    "linkage_specification",
                    "declaration_list",
                ):
                    pending.append((child, scope))
                elif kind in ("class_specifier", "struct_specifier"):
                    self._class(child, scope, names, result)
                elif kind in ("declaration", "type_definition", "field_declaration"):
                    if child.has_error:
                        continue  # C++'s compiler reports it; what it declares is unknown
                    specifier = child.child_by_field_name("type")
                    if specifier is not None and specifier.type in (
                        "class_specifier",
                        "struct_specifier",
                    ):
                        self._class(specifier, scope, names, result)
                    for index in range(child.child_count):
                        if child.field_name_for_child(index) != "declarator":
                            continue
                        declarator = child.children[index]
                        if declarator.type == "function_declarator":
                            target = declarator.child_by_field_name("declarator")
                            parameters = declarator.child_by_field_name("parameters")
                            if target is not None and parameters is not None:
                                functions.add(self.text.text(target))
                                types = tuple(self.functions.parameters(parameters).types)
                                line = self.text.position(self.text.span(child)[0])[0]
                                declared.setdefault(self.text.text(target), {})[types] = line
                        elif declarator.type in ("identifier", "type_identifier"):
                            names.add(self.text.text(declarator))
                        elif declarator.type == "init_declarator":
                            inner = declarator.child_by_field_name("declarator")
                            if inner is not None and inner.type == "identifier":
                                names.add(self.text.text(inner))
                elif kind in ("alias_declaration", "enum_specifier", "preproc_def"):
                    named = child.child_by_field_name("name")
                    if named is not None:
                        names.add(self.text.text(named))
        result.header_names = frozenset(names)
        result.header_functions = frozenset(functions)
        result.header_overloads = {
            name: tuple(sorted(lines.values()))
            for name, lines in declared.items()
            if len(lines) > 1
        }
        result.header_opaque = opaque
        result.namespaces = frozenset(namespaces)

    def _class(
        self, node: tree_sitter.Node, scope: str, names: set[str], result: CppLayerFile
    ) -> None:
        name = node.child_by_field_name("name")
        body = node.child_by_field_name("body")
        if name is None:
            return
        names.update({self.text.text(name), f"{scope}{self.text.text(name)}"})
        # (tree-sitter may stumble inside a valid body, `= {}` defaults for one: the body
        # counts when its closing brace is really there.)
        if body is None or body.children[-1].type != "}" or body.children[-1].is_missing:
            return
        # A body with a syntax error may misplace its members' parts: their declarations are
        # not compared (the C++ compiler reports the error).
        broken = body.has_error
        methods: dict[str, list[DeclaredMethod]] = {}
        static_methods: set[str] = set()
        has_macro = False
        for member in body.named_children:
            if "CONTEXTROS_LAYERED_CLASS" in [self.text.text(leaf) for leaf in leaves(member)]:
                has_macro = True
            declarator = function_declarator(member.child_by_field_name("declarator"))
            if declarator is None:
                continue
            target = declarator.child_by_field_name("declarator")
            parameters = declarator.child_by_field_name("parameters")
            if target is None or parameters is None:
                continue
            method = self.text.text(target)
            shape = self.functions.signature(member, declarator, target, parameters).shape
            line = self.text.position(self.text.span(member)[0])[0]
            methods.setdefault(method, []).append(DeclaredMethod(shape, shape.text(method), line))
            if any(
                child.type == "storage_class_specifier" and self.text.text(child) == "static"
                for child in member.children
            ):
                static_methods.add(method)
        close = self.text.char(body.children[-1].start_byte)
        overloads = {
            method: tuple(d.line for d in found)
            for method, found in methods.items()
            if len({d.shape.parameters for d in found}) > 1
        }
        result.classes.append(
            CppClass(
                f"{scope}{self.text.text(name)}",
                close,
                has_macro,
                frozenset(methods),
                {m: d[0] for m, d in methods.items() if len(d) == 1 and not broken},
                frozenset(static_methods),
                overloads,
            )
        )
