"""The pre-compiler: a `.layers` file becomes an ordinary, readable Python module.

Following the paper (section 5.3), every implementation becomes a module-level function
named `<method>_<Layer>` (`Class_method_<Layer>` for a method of a class), and each
method gets one dispatch function under its own name. The dispatch function is the
core's stable layered function: the core rewires it once per layer switch (it takes the
code of the head of the new chain), so a call does no look-up of any kind.

The same text is what `contextros compile` writes and what the loader runs; the loader
compiles it with every position mapped back to the `.layers` file, so tracebacks from
a layer method show the layer file's line.
"""

from __future__ import annotations

import ast
import copy
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from types import CodeType

from contextros.language.checker import checked
from contextros.language.diagnostics import Diagnostic, source_lines
from contextros.language.flavours import read_source
from contextros.language.python_syntax import PythonFunction, guard_function_lines, guard_name
from contextros.language.syntax import Function, Hook, LayerDecl, LayerFile, Ref, SourceLine
from contextros.language.words import RELATIONS

# Bumped whenever the generated code changes shape: it invalidates the loader's cache.
COMPILER_VERSION = 1

_RULE = "# " + "-" * 90


@dataclass(frozen=True)
class _Glue:
    """A generated line; it maps to the `.layers` line of the declaration it implements."""

    text: str
    line: int


_Line = SourceLine | _Glue


@dataclass
class CompiledLayers:
    """The result of compiling one layer file: the module text and its line map."""

    path: str
    text: str
    origins: list[_Line]
    warnings: list[Diagnostic] = field(default_factory=list)
    layer_file: LayerFile | None = None

    def code(self) -> CodeType:
        """The module's code, with `co_filename` and every position in the `.layers` file."""
        tree = ast.parse(self.text, filename=f"<compiled {self.path}>")
        lines = source_lines(self.layer_file.source) if self.layer_file else []
        for node in ast.walk(tree):
            _relocate(node, self.origins, lines)
        return compile(tree, self.path, "exec", dont_inherit=True)


def compile_source(source: str, path: str = "<layers>") -> CompiledLayers:
    """Check and translate a Python layer file; raise `LayerSyntaxError` if it has errors.

    (C++ layer files: `contextros.language.cpp.generator.compile_cpp`.)
    """
    layer_file, diagnostics = checked(source, path, "python")
    emitter = _Emitter(layer_file)
    emitter.module()
    return CompiledLayers(
        path=path,
        text="".join(line.text + "\n" for line in emitter.out),
        origins=emitter.out,
        warnings=[d for d in diagnostics if not d.is_error],
        layer_file=layer_file,
    )


def compile_file(path: str | os.PathLike[str]) -> CompiledLayers:
    return compile_source(read_source(path), str(path))


def _relocate(node: ast.AST, origins: list[_Line], source_lines: list[str]) -> None:
    """Move a node of the generated text to its place in the `.layers` file."""
    lineno = getattr(node, "lineno", None)
    if lineno is None:
        return
    end_lineno = getattr(node, "end_lineno", None) or lineno
    start, end = origins[lineno - 1], origins[end_lineno - 1]
    if isinstance(start, SourceLine) and isinstance(end, SourceLine):
        node.lineno = start.line  # type: ignore[attr-defined]
        node.col_offset = start.column(node.col_offset)  # type: ignore[attr-defined]
        node.end_lineno = end.line  # type: ignore[attr-defined]
        end_col = getattr(node, "end_col_offset", None)
        if end_col is not None:
            node.end_col_offset = end.column(end_col)  # type: ignore[attr-defined]
        # Python refuses inverted ranges; only a renamed `def` line could produce one.
        if node.end_lineno < node.lineno:  # type: ignore[attr-defined]
            node.end_lineno = node.lineno  # type: ignore[attr-defined]
        if node.end_lineno == node.lineno and (node.end_col_offset or 0) < node.col_offset:  # type: ignore[attr-defined]
            node.end_col_offset = node.col_offset  # type: ignore[attr-defined]
        return
    # Generated code (or a node spanning it): the whole declaration line.
    line = start.line
    text = source_lines[line - 1] if 0 < line <= len(source_lines) else ""
    node.lineno = node.end_lineno = line  # type: ignore[attr-defined]
    node.col_offset = len(text) - len(text.lstrip())  # type: ignore[attr-defined]
    node.end_col_offset = len(text.rstrip())  # type: ignore[attr-defined]


def _first_of_each(functions: Iterable[Function]) -> list[tuple[str, list[Function]]]:
    grouped: dict[str, list[Function]] = {}
    for function in functions:
        grouped.setdefault(function.key, []).append(function)
    return list(grouped.items())


class _Emitter:
    def __init__(self, layer_file: LayerFile) -> None:
        self.file = layer_file
        self.name = os.path.basename(layer_file.path)
        self.out: list[_Line] = []

    def glue(self, text: str, line: int) -> None:
        for part in text.split("\n"):
            self.out.append(_Glue(part, line))

    def blank(self, line: int, count: int = 1) -> None:
        self.glue("\n" * (count - 1), line)

    def module(self) -> None:
        self.preamble()
        lines = source_lines(self.file.source)[: self.file.header_lines]
        while lines and not lines[-1].strip():
            lines.pop()
        for number, text in enumerate(lines, start=1):
            self.out.append(SourceLine(text, number, 0))
        if lines:
            self.blank(1, 2)
        first = self.file.header_lines + 1
        self.imports(first)
        self.layers()
        for key, functions in _first_of_each(sorted(self.file.all_functions(), key=_position)):
            self.method(key, functions)
        self.metadata(first)

    def preamble(self) -> None:
        self.glue(
            f"# Generated by `contextros compile` from {self.name}: edit that file, not this one.\n"
            "#\n"
            "# Each method has one dispatch function under its own name (for a method of a\n"
            "# class, installed on the class) and one function per layer, <method>_<Layer>.\n"
            "# The dispatch function is the core's stable layered function: on every layer\n"
            "# switch the core composes the chain of active implementations once and gives the\n"
            "# dispatch function the code of its head, so a call runs the active layer's\n"
            "# function directly, with no look-up per call. proceed(...) in a layer's function\n"
            "# is bound to the next implementation at that time. A `# <file>:<line>` comment\n"
            "# names the source of the code below it; contextros.load() and the import hook\n"
            "# compile this module so that tracebacks show those lines.",
            1,
        )

    def imports(self, line: int) -> None:
        self.glue(
            f"{_RULE}\n# Generated from the layer declarations of {self.name}.\n"
            "from contextros.core import Layer as _Layer\n"
            "from contextros.core import layered as _layered\n"
            "from contextros.core import proceed",
            line,
        )
        if any(f.owner for f in self.file.all_functions()):
            self.glue(
                "from contextros.language.targets import layered_method as _layered_method", line
            )
        self.blank(line)

    def source(self, lines: Sequence[SourceLine], comment: str, decorator: str = "") -> None:
        self.glue(f"# {self.name}:{lines[0].line} ({comment})", lines[0].line)
        if decorator:
            self.glue(decorator, lines[0].line)
        self.out.extend(lines)

    # -- layers -------------------------------------------------------------------------

    def layers(self) -> None:
        group_of = {ref.name: g.name for g in self.file.groups for ref in g.members}
        for layer in self.file.layers:
            self.blank(layer.at.line)
            for hook in layer.hooks:
                self.hook(hook)
            self.layer(layer, group_of.get(layer.name))

    def hook(self, hook: Hook) -> None:
        self.source(hook.lines, f"layer {hook.layer}, on {hook.event}")
        self.blank(hook.at.line)

    def layer(self, layer: LayerDecl, group: str | None) -> None:
        arguments: list[str] = []
        if layer.description is not None:
            arguments.append(f"description={_literal(layer.description)}")
        if group is not None:
            arguments.append(f"group={_literal(group)}")
        for relation in RELATIONS:
            names = _unique(ref.name for ref in getattr(layer, relation))
            if names:
                arguments.append(f"{relation}={_names_tuple(names)}")
        for hook in layer.hooks:
            arguments.append(f"on_{hook.event}={hook.generated_name}")
        self.glue(f"# {self.name}:{layer.at.line}", layer.at.line)
        if not arguments:
            self.glue(f"{layer.name} = _Layer({_literal(layer.name)})", layer.at.line)
            return
        self.glue(f"{layer.name} = _Layer(\n    {_literal(layer.name)},", layer.at.line)
        for argument in arguments:
            self.glue(f"    {argument},", layer.at.line)
        self.glue(")", layer.at.line)

    # -- methods ------------------------------------------------------------------------

    def method(self, key: str, implementations: list[Function]) -> None:
        functions = [_python(f) for f in implementations]
        base = next((f for f in functions if f.layer is None), None)
        partials = [f for f in functions if f.layer is not None]
        first = functions[0]
        line = first.at.line
        self.glue(f"\n\n{_RULE}", line)
        if first.owner is None:
            self.glue(f"# {key}: dispatch function, then one function per layer.\n", line)
            if base is not None:
                self.source(base.lines, "base", decorator="@_layered")
            else:
                self.stub(first)
        else:
            self.glue(f"# {key}: a layered method installed on class {first.owner}.", line)
            self.glue(
                "# When the class comes from another module, the core reaches the functions\n"
                "# below through a one-line trampoline (a class of the header needs none).",
                line,
            )
            if base is not None:
                self.source(base.lines, "base")
        for partial in partials:
            self.blank(partial.at.line)
            self.source(partial.lines, f"layer {partial.layer}")
            if partial.guard is not None:
                self.guard(partial)
        self.blank(line)
        dispatch = key if first.owner is None else f"{first.owner}_{first.name}"
        if first.owner is not None:
            where = f"({_literal(self.file.path)}, {first.at.line}, {first.at.col})"
            self.glue(
                f"{dispatch} = _layered_method(\n"
                f"    {first.owner}, {_literal(first.name)}, "
                f"base={dispatch if base is not None else None}, where={where}\n)",
                line,
            )
        for partial in partials:
            when = f", when={guard_name(partial)}" if partial.guard is not None else ""
            self.glue(
                f"{dispatch}.partial({partial.layer}{when})({partial.generated_name})",
                partial.at.line,
            )

    def guard(self, partial: PythonFunction) -> None:
        """`when CONDITION` as a function of the partial's parameters, run on each call."""
        assert partial.node is not None and partial.guard is not None
        self.blank(partial.guard.at.line)
        self.glue(
            f"# {self.name}:{partial.guard.at.line} (layer {partial.layer}, guard)",
            partial.guard.at.line,
        )
        for line in guard_function_lines(partial.guard_lines, partial.node, guard_name(partial)):
            if isinstance(line, SourceLine):
                self.out.append(line)
            else:
                self.glue(line, partial.guard.at.line)

    def stub(self, first: PythonFunction) -> None:
        """The dispatch function of a method without base: a signature and a docstring."""
        assert first.node is not None
        stub = copy.copy(first.node)
        stub.name = first.name
        stub.decorator_list = []
        stub.body = [
            ast.Expr(
                ast.Constant(
                    f"Dispatch of {first.name}: runs the active layer's "
                    f"{first.name}_<Layer>; no base implementation."
                )
            )
        ]
        self.glue(f"@_layered(base=False)\n{ast.unparse(stub)}", first.at.line)

    def metadata(self, line: int) -> None:
        names = ", ".join(layer.name for layer in self.file.layers)
        order = [
            (layer.name, ref.name)
            for layer in self.file.layers
            for ref in _unique_refs(layer.after)
        ]
        self.glue(
            f"\n\n{_RULE}\n# The layers of this file, and the orders declared with 'after'.", line
        )
        self.glue(f"__layers__ = ({names}{',' if len(self.file.layers) == 1 else ''})", line)
        pairs = [_names_tuple(pair) for pair in order]
        self.glue(f"__layer_order__ = ({', '.join(pairs)}{',' if len(pairs) == 1 else ''})", line)


def _python(function: Function) -> PythonFunction:
    if not isinstance(function, PythonFunction):
        raise TypeError(f"the Python back end got a {type(function).__name__}")
    return function


def _literal(value: str) -> str:
    """A string literal, double-quoted like the rest of the code base."""
    text = repr(value)
    if text.startswith("'") and '"' not in value:
        text = '"' + text[1:-1].replace("\\'", "'") + '"'
    return text


def _names_tuple(names: Iterable[str]) -> str:
    items = [_literal(name) for name in names]
    return f"({items[0]},)" if len(items) == 1 else f"({', '.join(items)})"


def _position(function: Function) -> tuple[int, int]:
    return (function.at.line, function.at.col)


def _unique(names: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(names))


def _unique_refs(refs: Iterable[Ref]) -> list[Ref]:
    seen: dict[str, Ref] = {}
    for ref in refs:
        seen.setdefault(ref.name, ref)
    return list(seen.values())
