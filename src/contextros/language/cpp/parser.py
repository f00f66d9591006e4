"""The C++ flavour's parser: a header part of plain C++, then `Layer Name [ ... ]` blocks.

The layer language's own structure (declarations, relations, brackets) is read from
tree-sitter's tokens of the file, so brackets, strings and comments inside C++ never
confuse it; every block's content is parsed by tree-sitter's C++ grammar as function
definitions. The result is the language-neutral tree of syntax.py, with `CppFunction`s
carrying the text spans the back end rewrites.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import tree_sitter

from contextros.language.cpp.tokens import (
    SourceText,
    Token,
    first_problem,
    identifier_char,
    leaves,
    tokens,
)
from contextros.language.diagnostics import Diagnostic, DiagnosticSink
from contextros.language.lines import LINE_WORDS, is_line_declaration, parse_line_declaration
from contextros.language.syntax import (
    BaseBlock,
    Function,
    GroupDecl,
    Guard,
    Hook,
    LayerDecl,
    LayerFile,
    Position,
    ProceedCall,
    Ref,
    Signature,
)
from contextros.language.words import found_text, misspelt

LAYER_WORDS = ("Layer", "layer")
RELATIONS = ("excludes", "requires", "after")
DECLARATION_WORDS = (*LAYER_WORDS, "group", "base", *LINE_WORDS)

CPP_KEYWORDS = frozenset(
    {
        "alignas",
        "alignof",
        "and",
        "and_eq",
        "asm",
        "auto",
        "bitand",
        "bitor",
        "bool",
        "break",
        "case",
        "catch",
        "char",
        "char8_t",
        "char16_t",
        "char32_t",
        "class",
        "compl",
        "concept",
        "const",
        "consteval",
        "constexpr",
        "constinit",
        "const_cast",
        "continue",
        "co_await",
        "co_return",
        "co_yield",
        "decltype",
        "default",
        "delete",
        "do",
        "double",
        "dynamic_cast",
        "else",
        "enum",
        "explicit",
        "export",
        "extern",
        "false",
        "float",
        "for",
        "friend",
        "goto",
        "if",
        "inline",
        "int",
        "long",
        "mutable",
        "namespace",
        "new",
        "noexcept",
        "not",
        "not_eq",
        "nullptr",
        "operator",
        "or",
        "or_eq",
        "private",
        "protected",
        "public",
        "register",
        "reinterpret_cast",
        "requires",
        "return",
        "short",
        "signed",
        "sizeof",
        "static",
        "static_assert",
        "static_cast",
        "struct",
        "switch",
        "template",
        "this",
        "thread_local",
        "throw",
        "true",
        "try",
        "typedef",
        "typeid",
        "typename",
        "union",
        "unsigned",
        "using",
        "virtual",
        "void",
        "volatile",
        "wchar_t",
        "while",
        "xor",
        "xor_eq",
    }
)
# Names the generated code uses for itself.
RESERVED = frozenset({"proceed", "base"})


def name_problem(name: str) -> str:
    """Why `name` cannot name a layer or a group in generated C++ ('' if it can)."""
    if not name or not name.isascii() or not (name[0].isalpha() or name[0] == "_"):
        return "is not a C++ identifier"
    if not all(identifier_char(c) for c in name):
        return "is not a C++ identifier"
    if name in CPP_KEYWORDS:
        return "is a C++ keyword"
    if name in RESERVED or name.startswith("contextros_"):
        return "is reserved by the generated code"
    return ""


@dataclass
class CppFunction(Function):
    """A C++ implementation and where its parts are (character offsets in the layer file)."""

    start: int = 0
    end: int = 0
    target_start: int = 0  # of the (qualified) name
    name_start: int = 0
    name_end: int = 0
    params_open: int = 0  # just after '('
    params_close: int = 0  # at ')'
    no_parameters: bool = True  # `()` or `(void)`
    declarator_end: int = 0  # before the body
    defaults: tuple[tuple[int, int], ...] = ()  # ` = value` of parameters
    exception_specs: tuple[tuple[int, int], ...] = ()  # `noexcept(...)`, `throw(...)`
    parameter_names: tuple[str | None, ...] = ()
    body_start: int = 0  # at the body's '{'
    when_span: tuple[int, int] = (0, 0)  # `when (CONDITION)`, cut from the definition
    condition_span: tuple[int, int] = (0, 0)  # CONDITION itself

    @property
    def key(self) -> str:
        return f"{self.owner}::{self.name}" if self.owner else self.name


@dataclass
class CppHook(Hook):
    """`on activate { ... }`: the body is C++, a compound statement (offsets of its braces)."""

    body_start: int = 0
    body_end: int = 0


@dataclass
class _BlockItems:
    """What a block holds besides function definitions, found in its tokens: spans to hide
    from tree-sitter (each item is the layer language's, not C++) and the guards by offset."""

    masks: list[tuple[int, int]] = field(default_factory=list)
    broken: bool = False  # an item was reported: the block's C++ is not parsed
    guards: list[tuple[int, int, int, int]] = field(default_factory=list)  # when, ), cond


@dataclass
class CppClass:
    """A class defined in the header part, which the compiler can extend."""

    name: str  # with its namespaces: ns::Robot
    close: int  # offset of the closing brace of its body
    has_macro: bool  # already holds CONTEXTROS_LAYERED_CLASS
    methods: frozenset[str]  # member functions it declares
    # The signature (shape, text, line) of each member function declared once.
    declarations: dict[str, tuple[tuple[object, ...], str, int]] = field(default_factory=dict)
    static_methods: frozenset[str] = frozenset()  # declared `static`: a layer cannot refine them
    overloads: dict[str, tuple[int, ...]] = field(default_factory=dict)  # name: its lines


@dataclass
class CppLayerFile(LayerFile):
    classes: list[CppClass] = field(default_factory=list)
    header_functions: frozenset[str] = frozenset()  # functions the header part declares
    # Functions the header part declares more than once with different parameters: lines.
    header_overloads: dict[str, tuple[int, ...]] = field(default_factory=dict)
    header_end: int = 0  # character offset where the declarations start
    namespaces: frozenset[str] = frozenset()  # namespaces the header part opens (ns, ns::inner)

    def is_namespace(self, owner: str) -> bool:
        return any(ns == owner or ns.endswith("::" + owner) for ns in self.namespaces)

    def class_named(self, owner: str) -> CppClass | None:
        for cls in self.classes:
            if cls.name == owner or cls.name.endswith("::" + owner):
                return cls
        return None


def parse_with_diagnostics(
    source: str, path: str = "<layers>"
) -> tuple[CppLayerFile, list[Diagnostic]]:
    """Parse as far as possible and return the tree with all diagnostics (never raises them)."""
    return _Parser(source, path).run()


def _normalized(parts: list[str]) -> str:
    text = ""
    for part in parts:
        glue = "" if not text or text.endswith(("::", "(", "<", "~")) else " "
        if part in ("::", ",", ")", ">", "&", "&&", "*") or part.startswith("("):
            glue = "" if part in ("::", ",", ")", ">") else glue
        text += glue + part
    return text


class _Parser:
    def __init__(self, source: str, path: str) -> None:
        self.text = SourceText(source)
        self.source = source
        self.path = path
        self.sink = DiagnosticSink(path, source, syntax=True)

    def error(self, message: str, offset: int) -> None:
        line, col = self.text.position(offset)
        self.sink.error(message, line, col)

    def at(self, offset: int) -> Position:
        return Position(*self.text.position(offset))

    # -- file level ---------------------------------------------------------------------

    def run(self) -> tuple[CppLayerFile, list[Diagnostic]]:
        header_end = self._header_end()
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
        self._header(result)
        # `rule`, `parameter`, `lifecycle` and `topic` lines: the shared, neutral grammar;
        # then blanked out, so the C++ tokens of the rest keep their offsets.
        masked = self._line_declarations(header_end, result)
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
            if declared is None or declared[0] == function.signature.shape:
                continue
            self.sink.error(
                f"incompatible signature: {function.signature.text} does not match the "
                f"declaration {declared[1]} in class {function.owner} (line {declared[2]})",
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

    def _header_end(self) -> int:
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

    def _line_declarations(self, header_end: int, result: CppLayerFile) -> str:
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
        misspelt = word not in DECLARATION_WORDS and _misspelt(word)
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

    def _header(self, result: CppLayerFile) -> None:
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
                                types = tuple(self._parameters(parameters)[0])
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
        methods: dict[str, list[tuple[tuple[object, ...], str, int]]] = {}
        static_methods: set[str] = set()
        has_macro = False
        for member in body.named_children:
            if "CONTEXTROS_LAYERED_CLASS" in [self.text.text(leaf) for leaf in leaves(member)]:
                has_macro = True
            declarator = _function_declarator(member.child_by_field_name("declarator"))
            if declarator is None:
                continue
            target = declarator.child_by_field_name("declarator")
            parameters = declarator.child_by_field_name("parameters")
            if target is None or parameters is None:
                continue
            method = self.text.text(target)
            shape, types, *_ = self._shape(member, declarator, target, parameters)
            text = f"{shape[0]} {method}({', '.join(types)})" + (f" {shape[2]}" if shape[2] else "")
            line = self.text.position(self.text.span(member)[0])[0]
            methods.setdefault(method, []).append((shape, text, line))
            if any(
                child.type == "storage_class_specifier" and self.text.text(child) == "static"
                for child in member.children
            ):
                static_methods.add(method)
        close = self.text.char(body.children[-1].start_byte)
        overloads = {
            method: tuple(d[2] for d in found)
            for method, found in methods.items()
            if len({d[0][1] for d in found}) > 1
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

    # -- declarations -------------------------------------------------------------------

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
                found_word = found_text(token.text, ("Layer", "group", "base"))
                self.error(
                    f"expected a declaration ('Layer', 'base' or 'group'), found {found_word}"
                    "; C++ code belongs in the header part, above the first "
                    "declaration, or in a layer's [ ... ] block",
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
            self.error(f"expected 'excludes', 'requires', 'after' or '['{got}", where)
            return self._recover(found, j)
        result.layers.append(layer)  # declared, even if its block is broken
        close, paired = self._block_end(found, j)
        if close is None:
            return self._recover(found, j + 1)
        if paired:
            items = self._block_items(found[j : close + 1], layer)
            functions = self._functions(found[j], found[close], layer.name, result, items)
            layer.functions.extend(functions)
        return close + 1

    def _base(self, found: list[Token], i: int, result: CppLayerFile) -> int:
        j = i + 1
        if j >= len(found) or found[j].text != "[":
            self.error(
                "expected '[' after 'base'", found[j].start if j < len(found) else found[i].end
            )
            return self._recover(found, j)
        close, paired = self._block_end(found, j)
        if close is None:
            return self._recover(found, j + 1)
        block = BaseBlock(self.at(found[i].start))
        result.bases.append(block)
        if paired:
            items = self._block_items(found[j : close + 1], None)
            block.functions.extend(self._functions(found[j], found[close], None, result, items))
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

    def _block_end(self, found: list[Token], open_index: int) -> tuple[int | None, bool]:
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
                    f"{self._where(found[open_index])} is not closed",
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
                        f"{text!r} does not close the {top.text!r} at {self._where(top)}: "
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

    def _where(self, token: Token) -> str:
        line, col = self.text.position(token.start)
        return f"{line}:{col}"

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

    def _block_items(self, block: list[Token], layer: LayerDecl | None) -> _BlockItems:
        """The layer language's items inside a block, at its top level (outside braces): a
        description (a string literal first), `on activate { ... }` / `on deactivate { ... }`
        hooks and `when (CONDITION)` guards between a definition's declarator and body."""
        items = _BlockItems()
        where = f"layer {layer.name}" if layer is not None else "the base block"
        errors = len(self.sink.items)
        braces = parens = 0
        item_start = True  # at the start of an item (not inside a definition)
        declarator = False  # a definition's parameter list has closed
        k = 1
        end = len(block) - 1  # the closing ']'
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
                k = self._description(block, k, end, layer, where, items)
                continue
            if text == "on" and item_start and k + 1 < end and block[k + 1].text.isidentifier():
                k = self._hook(block, k, end, layer, where, items)
                continue
            if text in ("activate", "deactivate") and item_start and block[k + 1].text == "{":
                self.error(
                    f"expected 'on' before {text!r}: a hook is 'on {text} {{ ... }}'", token.start
                )
                k += 1
                continue
            if text == "when" and declarator and k + 1 < end and block[k + 1].text == "(":
                k = self._guard(block, k, end, items)
                continue
            braces += text == "{"
            parens += text == "("
            item_start = text == ";"
            k += 1
        items.broken = len(self.sink.items) > errors
        return items

    def _description(
        self,
        block: list[Token],
        k: int,
        end: int,
        layer: LayerDecl | None,
        where: str,
        items: _BlockItems,
    ) -> int:
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
                f"a description is a string literal first in a layer's block, not here in {where}",
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

    def _hook(
        self,
        block: list[Token],
        k: int,
        end: int,
        layer: LayerDecl | None,
        where: str,
        items: _BlockItems,
    ) -> int:
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
        depth = 0
        close = k + 2
        while close < end:
            depth += {"{": 1, "}": -1}.get(block[close].text, 0)
            if depth == 0:
                break
            close += 1
        items.masks.append((on.start, block[close].end))
        if layer is None:
            self.error(f"'on {event.text}' belongs to a layer: {where} has no hooks", on.start)
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

    def _guard(self, block: list[Token], k: int, end: int, items: _BlockItems) -> int:
        depth = 0
        close = k + 1
        while close < end:
            depth += {"(": 1, ")": -1}.get(block[close].text, 0)
            if depth == 0:
                break
            close += 1
        if close >= end:
            self.error("this guard's '(' is not closed", block[k + 1].start)
            return end
        if close == k + 2:
            self.error("expected a condition in 'when ( )'", block[k + 1].end)
        items.masks.append((block[k].start, block[close].end))
        items.guards.append(
            (block[k].start, block[close].end, block[k + 1].end, block[close].start)
        )
        return close + 1

    def _functions(
        self,
        opening: Token,
        closing: Token,
        layer: str | None,
        result: CppLayerFile,
        items: _BlockItems,
    ) -> list[Function]:
        owner_text = f"layer {layer}" if layer is not None else "the base block"
        original = self.text
        if items.masks:  # the layer language's items become blanks: C++ is left
            masked = self.source
            for a, b in items.masks:
                blank = "".join(c if c in "\r\n" else " " for c in masked[a:b])
                masked = masked[:a] + blank + masked[b:]
            self.text = SourceText(masked)
        try:
            functions = (
                []
                if items.broken
                else self._parsed_functions(opening, closing, layer, owner_text, items)
            )
        finally:
            self.text = original
        hooks = any(m for m in items.masks if m not in [(g[0], g[1]) for g in items.guards])
        if not functions and not hooks and not self.sink.has_errors:
            self.error(
                f"{owner_text} is empty: expected function definitions between '[' and ']'",
                opening.start,
            )
        return functions

    def _parsed_functions(
        self,
        opening: Token,
        closing: Token,
        layer: str | None,
        owner_text: str,
        items: _BlockItems,
    ) -> list[Function]:
        tree = self.text.parse(opening.end, closing.start)
        functions: list[Function] = []
        for child in tree.root_node.named_children:
            start, _ = self.text.span(child)
            if child.type == "comment" or start < opening.end or start >= closing.start:
                continue
            if child.type != "function_definition":
                what = "a template" if child.type == "template_declaration" else None
                problem = first_problem(child) if child.type != "ERROR" else _stray(child)
                if what:
                    self.error(
                        f"{what} cannot be layered (its dispatch would need one layered "
                        f"function per instantiation) in {owner_text}: write a plain function "
                        "per type you need (name_int, name_double), layer those, and have the "
                        "template in the header part call them",
                        start,
                    )
                elif problem is not None and problem is not child:
                    self._syntax_error(problem)
                else:
                    self.error(
                        "expected a C++ function definition (a free function or Class::method) "
                        f"in {owner_text}",
                        start,
                    )
                continue
            function = self._function(child, layer)
            if function is not None:
                self._attach_guard(function, items)
                functions.append(function)
        return functions

    def _attach_guard(self, function: CppFunction, items: _BlockItems) -> None:
        for when, close, cond_start, cond_end in items.guards:
            if function.declarator_end <= when < function.body_start:
                function.when_span = (when, close)
                function.condition_span = (cond_start, cond_end)
                text = self.source[cond_start:cond_end]
                offset = cond_start + len(text) - len(text.lstrip())
                function.guard = Guard(text.strip(), self.at(offset))
                if None in function.parameter_names:
                    self.error(
                        f"a guarded implementation of {function.key} must name every "
                        "parameter: the calls its guard turns away go on with them to the next "
                        "implementation",
                        offset,
                    )
                return

    def _syntax_error(self, node: tree_sitter.Node) -> None:
        start, end = self.text.span(node)
        if node.is_missing:
            self.error(f"C++ syntax error: missing {node.type!r}", start)
            return
        stray = _stray(node, in_body=False) if node.type == "ERROR" else node
        if stray is not node:
            start, end = self.text.span(stray)
        text = self.source[start:end].split("\n")[0].strip()
        self.error(f"C++ syntax error: unexpected {text[:40]!r}", start)

    def _function(self, node: tree_sitter.Node, layer: str | None) -> CppFunction | None:
        start, end = self.text.span(node)
        problem = first_problem(node)
        if problem is not None:
            self._syntax_error(problem)
            return None
        ref = _ref_qualifier(node.child_by_field_name("declarator"))
        if ref is not None:
            self.error(
                f"a ref-qualified method ('{self.text.text(ref)}') cannot be layered: its dispatch "
                "is a plain method; drop the qualifier, or layer a plain method "
                "(name_layered) and call it from this one in the class",
                self.text.span(ref)[0],
            )
            return None
        for child in node.children:
            if child.type in ("storage_class_specifier", "virtual", "explicit"):
                self.error(
                    f"{self.text.text(child)!r} is not allowed on a layer's function: the "
                    "dispatch function is what others call",
                    self.text.span(child)[0],
                )
                return None
        declarator = _function_declarator(node.child_by_field_name("declarator"))
        body = node.child_by_field_name("body")
        if declarator is None or body is None:
            self.error("expected a function definition with a body", start)
            return None
        target = declarator.child_by_field_name("declarator")
        parameters = declarator.child_by_field_name("parameters")
        assert target is not None and parameters is not None
        owner: str | None = None
        name_node = target
        if target.type == "qualified_identifier":
            while name_node.type == "qualified_identifier":
                inner_name = name_node.child_by_field_name("name")
                if inner_name is None:
                    break
                name_node = inner_name
            scope_end = self.text.span(name_node)[0]
            owner = "".join(self.source[self.text.span(target)[0] : scope_end].split())
            owner = owner.removesuffix("::")
        if name_node.type != "identifier" or (owner is not None and not owner):
            self.error(
                f"cannot layer {self.text.text(target)!r}: expected a function name or "
                "Class::method",
                self.text.span(target)[0],
            )
            return None
        name = self.text.text(name_node)
        name_start, name_end = self.text.span(name_node)
        shape, types, names, defaults, problem_at = self._shape(
            node, declarator, target, parameters
        )
        if problem_at is not None:
            self.error(problem_at[1], problem_at[0])
            return None
        key = f"{owner}::{name}" if owner else name
        text = f"{shape[0]} {key}({', '.join(types)})" + (f" {shape[2]}" if shape[2] else "")
        calls = tuple(
            ProceedCall(self.at(self.text.span(call)[0]))
            for call in _calls(body)
            if self.text.text(call.child_by_field_name("function") or call) == "proceed"
        )
        stem = f"{owner.replace('::', '_')}_{name}" if owner else name
        open_start, close_start = self.text.span(parameters)
        return CppFunction(
            name=name,
            owner=owner,
            layer=layer,
            at=self.at(name_start),
            generated_name=f"{stem}_{layer}" if layer is not None else f"{stem}_base",
            signature=Signature((shape[0], shape[1], shape[2]), text),
            proceed_calls=calls,
            takes_instance=True,
            instance_name="this",
            start=start,
            end=end,
            target_start=self.text.span(target)[0],
            name_start=name_start,
            name_end=name_end,
            params_open=open_start + 1,
            params_close=close_start - 1,
            no_parameters=not types,
            declarator_end=self.text.span(declarator)[1],
            defaults=tuple(defaults),
            exception_specs=tuple(
                self.text.span(child)
                for child in declarator.children
                if child.type in ("noexcept", "throw_specifier")
            ),
            parameter_names=tuple(names),
            body_start=self.text.span(body)[0],
        )

    def _shape(
        self,
        node: tree_sitter.Node,
        declarator: tree_sitter.Node,
        target: tree_sitter.Node,
        parameters: tree_sitter.Node,
    ) -> tuple[
        tuple[str, tuple[str, ...], str],
        list[str],
        list[str | None],
        list[tuple[int, int]],
        tuple[int, str] | None,
    ]:
        """What callers rely on: the return type, the parameter types, the qualifiers."""
        target_start = self.text.span(target)[0]
        # The return type: every token before the declarator's name, less what only a
        # declaration in a class says (virtual, static...).
        attributes = [
            self.text.span(child)
            for child in node.children
            if child.type in ("attribute_declaration", "attribute_specifier", "comment")
        ]
        returns = [
            self.text.text(leaf)
            for leaf in leaves(node)
            if self.text.span(leaf)[0] < target_start
            and self.text.text(leaf) not in _SPECIFIERS
            and not any(a <= self.text.span(leaf)[0] < b for a, b in attributes)
        ]
        types, names, defaults, problem_at = self._parameters(parameters)
        parameters_end = self.text.span(parameters)[1]
        qualifiers = [
            self.text.text(leaf)
            for child in declarator.children
            if self.text.span(child)[0] >= parameters_end and child.type != "virtual_specifier"
            for leaf in leaves(child)
        ]
        shape = (_normalized(returns), tuple(types), _normalized(qualifiers))
        return shape, types, names, defaults, problem_at

    def _parameters(
        self, parameters: tree_sitter.Node
    ) -> tuple[list[str], list[str | None], list[tuple[int, int]], tuple[int, str] | None]:
        types: list[str] = []
        names: list[str | None] = []
        defaults: list[tuple[int, int]] = []
        named = parameters.named_children
        for child in parameters.children:
            if child.type == "...":
                return (
                    [],
                    [],
                    [],
                    (self.text.span(child)[0], "C-style variadic functions cannot be layered"),
                )
        for parameter in named:
            start = self.text.span(parameter)[0]
            if parameter.type == "comment":
                continue
            if parameter.type not in ("parameter_declaration", "optional_parameter_declaration"):
                return (
                    [],
                    [],
                    [],
                    (
                        start,
                        "cannot layer a function with a parameter like "
                        f"{self.text.text(parameter)!r}",
                    ),
                )
            declarator = parameter.child_by_field_name("declarator")
            name_node = _declared_name(declarator) if declarator is not None else None
            default = parameter.child_by_field_name("default_value")
            cut = self.text.span(default)[1] if default is not None else None
            type_end = self.text.span(declarator)[1] if declarator is not None else None
            parts = [
                self.text.text(leaf)
                for leaf in leaves(parameter)
                if (name_node is None or leaf.start_byte != name_node.start_byte)
                and (type_end is None or default is None or self.text.span(leaf)[0] < type_end)
            ]
            if parts == ["void"] and len(named) == 1:
                break
            types.append(_normalized(parts))
            names.append(self.text.text(name_node) if name_node is not None else None)
            if default is not None and cut is not None and type_end is not None:
                defaults.append((type_end, cut))
        return types, names, defaults, None


# Said only where a member function is declared in its class, not where it is defined.
_SPECIFIERS = frozenset({"virtual", "static", "inline", "explicit", "friend", "constexpr"})


_CLOSER = {"(": ")", "[": "]", "{": "}", "[[": "]]"}
# A closing bracket of more strength than the open one's ends it too (a '}' ends a '(').
_STRENGTH = {")": 0, "]": 1, "]]": 1, "}": 2}


def _misspelt(word: str) -> str:
    return misspelt(word, ("Layer", "group", "base"))


# Tokens that may stand anywhere in broken code: keywords, brackets, ';'.
_NOT_STRAY = frozenset({"{", "}", ";", "(", ")", "[", "]"})


def _stray(error: tree_sitter.Node, *, in_body: bool = True) -> tree_sitter.Node:
    """In code tree-sitter could not read, the first punctuation that fits nowhere
    (`return x:`; in a definition: in its body), else the whole of it."""
    inside = not in_body
    for child in error.children:
        if child.type == "{":
            inside = True
        elif (
            inside
            and not child.is_named
            and not child.type.isidentifier()
            and (child.type not in _NOT_STRAY)
        ):
            return child
    return error


def _function_declarator(node: tree_sitter.Node | None) -> tree_sitter.Node | None:
    """The function declarator under pointer and reference declarators (`T& f()`), if any."""
    while node is not None and node.type in ("pointer_declarator", "reference_declarator"):
        inner = node.child_by_field_name("declarator")
        if inner is None:
            named = [c for c in node.named_children if c.type.endswith("declarator")]
            inner = named[0] if named else None
        node = inner
    return node if node is not None and node.type == "function_declarator" else None


def _ref_qualifier(node: tree_sitter.Node | None) -> tree_sitter.Node | None:
    """The `&` or `&&` after a method's parameters, if any."""
    declarator = _function_declarator(node)
    if declarator is None:
        return None
    return next((c for c in declarator.children if c.type == "ref_qualifier"), None)


def _declared_name(node: tree_sitter.Node) -> tree_sitter.Node | None:
    """The identifier a (possibly nested) parameter declarator declares."""
    current: tree_sitter.Node | None = node
    while current is not None:
        if current.type == "identifier":
            return current
        inner = current.child_by_field_name("declarator")
        if inner is None:
            nested = [
                c
                for c in current.named_children
                if c.type == "identifier" or c.type.endswith("declarator")
            ]
            inner = nested[0] if nested else None
        current = inner
    return None


def _calls(node: tree_sitter.Node) -> list[tree_sitter.Node]:
    found: list[tree_sitter.Node] = []
    stack = [node]
    while stack:
        current = stack.pop()
        if current.type == "call_expression":
            found.append(current)
        stack.extend(current.named_children)
    found.sort(key=lambda n: n.start_byte)
    return found


_STRINGS = ("string_literal", "raw_string_literal")
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "\\": "\\", '"': '"', "'": "'", "0": "\0"}


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
