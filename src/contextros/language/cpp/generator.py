"""The C++ back end: a checked C++ layer file becomes a source and a header (Listing 2).

For each method: one function per layer (`getPos_Indoor`; for a method of a class, a member
specialisation `Robot::contextros_impl<tag>` reached through `contextros::MethodThunk`), a
`contextros::Layered` object holding them, and the dispatch function under the method's own
name, whose body is one call of that object: one atomic load and one indirect call, rewired
by the runtime once per configuration (never an if/else over the active layers). The layers
and their relations are defined in the runtime at static initialisation.

`#line` directives put every piece of user code at its place in the layer file, so compiler
diagnostics and debuggers point there. The layer file's path there is absolute when it was
given so (CMake builds, whose compiler runs in the build directory), else relative to the
output's directory (or the bare file name): never dependent on the working directory.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field

from contextros.language.checker import checked
from contextros.language.cpp.tree import CppFunction, CppHook, CppLayerFile
from contextros.language.diagnostics import Diagnostic, DiagnosticSink, LayerSyntaxError
from contextros.language.syntax import Function, LayerDecl

_RULE = "// " + "-" * 90
# Replaced by a #line directive back to the generated file itself.
_RESET = "#line contextros-generated"


@dataclass
class CompiledCpp:
    """A compiled C++ layer file: the source, and its header unless it was inlined."""

    path: str
    source: str
    header: str | None
    header_name: str | None
    warnings: list[Diagnostic] = field(default_factory=list)


def line_file(path: str, output: str | None) -> str:
    """The name `#line` gives the layer file. Compilers print it as it is, and a reader
    opens it from where the compiler ran, which the generator cannot know: a layer file
    named by its absolute path (as CMake names it) keeps it; a relative one is named
    relative to the output's directory (where `g++ -c robot.layers.cpp` runs)."""
    if os.path.isabs(path):
        return path.replace(os.sep, "/")
    if output is None or output == "-" or path.startswith("<"):
        return os.path.basename(path)
    relative = os.path.relpath(os.path.abspath(path), os.path.dirname(os.path.abspath(output)))
    return relative.replace(os.sep, "/")


def header_name_for(output: str) -> str:
    base = os.path.basename(output)
    stem = base[: -len(".cpp")] if base.endswith(".cpp") else base
    return stem + ".hpp"


def compile_cpp(
    source: str, path: str = "<layers>", *, output: str | None = None, header: bool = True
) -> CompiledCpp:
    """Check and translate a C++ layer file; raise `LayerSyntaxError` if it has errors.

    `output` is the path the source will be written to: the header is named after it
    (`robot.layers.cpp` -> `robot.layers.hpp`) and `#line` paths are relative to it. Without
    a header (or with no output), the source holds the header part itself.
    """
    layer_file, diagnostics = checked(source, path, "cpp")
    assert isinstance(layer_file, CppLayerFile)
    return generate(
        layer_file, [d for d in diagnostics if not d.is_error], output=output, header=header
    )


def generate(
    layer_file: CppLayerFile,
    warnings: list[Diagnostic],
    *,
    output: str | None = None,
    header: bool = True,
) -> CompiledCpp:
    """Translate a checked file. `output` is where the source goes (for names and paths)."""
    output_name = os.path.basename(output) if output not in (None, "-") else "<stdout>"
    emitter = _Emitter(layer_file, line_file(layer_file.path, output), output_name or "")
    header_name = header_name_for(output) if header and output not in (None, "-") else None
    header_text, source_text = emitter.run(header_name)
    return CompiledCpp(layer_file.path, source_text, header_text, header_name, warnings)


def _reset_lines(text: str, name: str) -> str:
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if line == _RESET:
            lines[index] = f"#line {index + 2} {_quote(name)}"
    return "\n".join(lines)


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _names(names: Iterable[str]) -> str:
    items = list(dict.fromkeys(names))
    return "{" + ", ".join(_quote(n) for n in items) + "}"


def _unix(text: str) -> str:
    return text.replace("\r\n", "\n").replace("\r", "\n")


class _Emitter:
    def __init__(self, layer_file: CppLayerFile, line_name: str, output_name: str) -> None:
        self.output_name = output_name
        self.file = layer_file
        self.name = os.path.basename(layer_file.path)
        self.line_name = line_name
        self.source = layer_file.source
        self.sink = DiagnosticSink(layer_file.path, layer_file.source)
        self.methods: dict[str, list[CppFunction]] = {}
        for function in sorted(self.file.all_functions(), key=lambda f: (f.at.line, f.at.col)):
            assert isinstance(function, CppFunction)
            self.methods.setdefault(function.key, []).append(function)

    def line(self, line: int) -> str:
        return f"#line {line} {_quote(self.line_name)}"

    def position(self, offset: int) -> tuple[int, int]:
        before = self.source[:offset]
        line = before.count("\n") + before.count("\r") - before.count("\r\n") + 1
        start = max(before.rfind("\n"), before.rfind("\r")) + 1
        return line, offset - start + 1

    # -- the whole output ---------------------------------------------------------------

    def run(self, header_name: str | None) -> tuple[str | None, str]:
        header = self.header_text(header_name or "")
        source = [self.banner()]
        if header_name is not None:
            source.append(f'#include "{header_name}"\n')
        else:
            source.append(header)
        source.append(self.layers())
        for key, functions in self.methods.items():
            source.append(self.method(key, functions))
        errors = [d for d in self.sink.items if d.is_error]
        if errors:
            raise LayerSyntaxError(errors)
        header_out = self.banner() + header if header_name is not None else None
        source_name = self.output_name
        return (
            _reset_lines(header_out, header_name)
            if header_out is not None and header_name is not None
            else None,
            _reset_lines("".join(source), source_name),
        )

    def banner(self) -> str:
        return (
            f"// Generated by `contextros compile` from {self.name}: edit that file, not this "
            "one.\n"
            "//\n"
            "// Each method has one function per layer (<method>_<Layer>; for a method of a\n"
            "// class, the member Class::contextros_impl<tag>) and one dispatch function under\n"
            "// its own name. The dispatch function calls a contextros::Layered object: one\n"
            "// atomic load and one indirect call of the head of the chain of active\n"
            "// implementations, which the runtime (cpp/core) composes once per layer switch.\n"
            "// proceed(...) in a layer's function runs the next implementation of that chain.\n"
            "// #line directives name the lines of the layer file the code comes from.\n"
        )

    def header_text(self, header_name: str) -> str:
        out = ["#pragma once\n\n" if header_name else "\n", "#include <contextros/layered.hpp>\n\n"]
        text = self.file.header
        if text.strip():
            out.append(self.line(1) + "\n")
            out.append(_unix(self.injected(text)))
            if not text.endswith(("\n", "\r")):
                out.append("\n")
            out.append(_RESET + "\n")
        declarations = self.declarations()
        if declarations:
            out.append(f"\n{_RULE}\n// The dispatch functions of {self.name}.\n")
            out.extend(declarations)
        return "".join(out)

    def injected(self, text: str) -> str:
        """The header part, with what layered methods need added to its classes."""
        additions: dict[int, list[str]] = {}
        declared: dict[int, set[str]] = {}  # names declared by the compiler, per class
        for key, functions in self.methods.items():
            first = functions[0]
            if first.owner is None:
                continue
            cls = self.file.class_named(first.owner)
            if cls is None:
                continue
            parts = additions.setdefault(cls.close, [])
            names = declared.setdefault(cls.close, set())
            if first.name not in cls.methods and first.name not in names:
                names.add(first.name)
                declaration = self.declaration_text(
                    self.dispatch_source(functions), qualified=False
                )
                parts.append(f" public: {declaration};")
            if not cls.has_macro and " CONTEXTROS_LAYERED_CLASS;" not in parts:
                parts.append(" CONTEXTROS_LAYERED_CLASS;")
            del key
        for close in sorted(additions, reverse=True):
            parts = sorted(additions[close], key=lambda p: p != " CONTEXTROS_LAYERED_CLASS;")
            text = text[:close] + "".join(parts[1:] + parts[:1]) + " " + text[close:]
        return text

    def declarations(self) -> list[str]:
        out: list[str] = []
        for functions in self.methods.values():
            first = functions[0]
            if first.owner is not None or first.name in self.file.header_functions:
                continue
            chosen = self.dispatch_source(functions)
            line, col = self.position(chosen.start)
            text = self.declaration_text(chosen, qualified=True, keep_layout=True)
            out.append(f"{self.line(line)}\n{' ' * (col - 1)}{text};\n{_RESET}\n")
        return out

    # -- pieces of functions ----------------------------------------------------------------

    def dispatch_source(self, functions: list[CppFunction]) -> CppFunction:
        """The implementation whose declarator the dispatch function copies: the base's, else
        the first one that names all its parameters."""
        ordered = sorted(functions, key=lambda f: f.layer is not None)
        for function in ordered:
            if all(name is not None for name in function.parameter_names):
                return function
        return ordered[0]

    def declaration_text(
        self, function: CppFunction, *, qualified: bool, keep_layout: bool = False
    ) -> str:
        start = function.start if qualified else function.target_start
        text = self.source[function.start : function.declarator_end]
        if not qualified:
            text = (
                self.source[function.start : function.target_start]
                + self.source[function.name_start : function.declarator_end]
            )
        del start
        return _unix(text) if keep_layout else " ".join(text.split())

    def rewritten(
        self,
        function: CppFunction,
        *,
        name: str | None,
        parameter: str | None,
        end: int,
        strip_defaults: bool,
        strip_exception_specs: bool = False,
    ) -> str:
        """The function's text up to `end`, renamed, with a leading parameter, no defaults."""
        edits: list[tuple[int, int, str]] = []
        if name is not None:
            edits.append((function.name_start, function.name_end, name))
        if parameter is not None:
            if function.no_parameters:
                edits.append((function.params_open, function.params_close, parameter))
            else:
                edits.append((function.params_open, function.params_open, parameter + ", "))
        if strip_defaults:
            edits.extend((a, b, "") for a, b in function.defaults)
        if strip_exception_specs:  # a member specialisation has the template's (none)
            edits.extend((a, b, "") for a, b in function.exception_specs)
        if function.guard is not None and end > function.body_start:
            # `when (CONDITION)` goes; the body starts by passing the call on when it fails.
            edits.append((*function.when_span, ""))
            edits.append((function.body_start + 1, function.body_start + 1, self.guard(function)))
        # After each edit, a #line and blanks put the rest back at its own line and column,
        # so diagnostics point exactly at the layer file's text.
        text = ""
        position = function.start
        for a, b, new in sorted(edits):
            text += _unix(self.source[position:a]) + new
            position = b
            if position < end:
                line, col = self.position(position)
                text += f"\n{self.line(line)}\n{' ' * (col - 1)}"
        return text + _unix(self.source[position:end])

    def guard(self, function: CppFunction) -> str:
        """The first statement of a guarded body: the condition at its place in the layer
        file; when it does not hold, the call goes on to the next implementation."""
        start, end = function.condition_span
        line, col = self.position(start)
        arguments = ", ".join(
            f"static_cast<decltype({n})&&>({n})" for n in function.parameter_names if n
        )
        condition = _unix(self.source[start:end])
        return (
            f" if (!(\n{self.line(line)}\n{' ' * (col - 1)}{condition})) "
            f"return proceed({arguments});"
        )

    def placed(self, function: CppFunction, text: str, prefix: str = "") -> str:
        line, col = self.position(function.start)
        if prefix:
            return f"{self.line(line - 1)}\n{prefix}\n{' ' * (col - 1)}{text}\n{_RESET}\n"
        return f"{self.line(line)}\n{' ' * (col - 1)}{text}\n{_RESET}\n"

    # -- layers and methods -------------------------------------------------------------------

    def layers(self) -> str:
        group_of = {ref.name: g.name for g in self.file.groups for ref in g.members}
        out = [
            f"\n{_RULE}\n// The layers of {self.name} and their relations, defined in the runtime "
            "at static\n// initialisation (contextros::defined_layers() lists them).\n",
            "namespace {\n\n",
        ]
        hooks = [h for layer in self.unique_layers() for h in layer.hooks]
        for hook in hooks:
            assert isinstance(hook, CppHook)
            out.append(self.hook(hook))
        out.append("[[maybe_unused]] const bool contextros_layers_defined = [] {\n")
        for layer in self.unique_layers():
            fields = [
                _quote(layer.name),
                _names(r.name for r in layer.excludes),
                _names(r.name for r in layer.requires),
                _names(r.name for r in layer.after),
                _quote(group_of.get(layer.name, "")),
            ]
            if layer.implies:
                fields.append(_names(r.name for r in layer.implies))
            arguments = f"{{{', '.join(fields)}}}"
            if layer.description is not None or layer.hooks:
                arguments += f", {_quote(layer.description or '')}"
            if layer.hooks:
                by_event = {h.event: f"&{h.generated_name}" for h in layer.hooks}
                on, off = by_event.get("activate", "{}"), by_event.get("deactivate", "{}")
                arguments += f", {{{on}, {off}}}"
            out.append(f"  ::contextros::define_layer({arguments});\n")
        out.append("  return true;\n}();\n\n}  // namespace\n")
        return "".join(out)

    def hook(self, hook: CppHook) -> str:
        """`on activate { ... }` as a function of no arguments, its body at its place."""
        line, col = self.position(hook.body_start)
        body = _unix(self.source[hook.body_start : hook.body_end])
        return (
            f"// The 'on {hook.event}' hook of layer {hook.layer}.\n"
            f"{self.line(hook.at.line)}\nvoid {hook.generated_name}()\n"
            f"{self.line(line)}\n{' ' * (col - 1)}{body}\n{_RESET}\n\n"
        )

    def unique_layers(self) -> list[LayerDecl]:
        seen: dict[str, LayerDecl] = {}
        for layer in self.file.layers:
            seen.setdefault(layer.name, layer)
        return list(seen.values())

    def method(self, key: str, functions: list[CppFunction]) -> str:
        first = functions[0]
        base = next((f for f in functions if f.layer is None), None)
        partials = [f for f in functions if f.layer is not None]
        if first.owner is None:
            signature = f"decltype({first.name})"
        else:
            signature = f"decltype(&{first.owner}::{first.name})"
        parameter = f"[[maybe_unused]] ::contextros::ProceedOf<{signature}> proceed"
        stem = (
            first.name if first.owner is None else f"{first.owner.replace('::', '_')}_{first.name}"
        )
        out = [f"\n{_RULE}\n// {key}: one function per layer, then the dispatch function.\n"]
        if first.owner is not None and self.file.class_named(first.owner) is None:
            # A class of an included header, or a namespace: only the C++ compiler can tell.
            line, col = first.at.line, first.at.col
            out.append(
                f"{self.line(line - 1)}\nstatic_assert(\n{' ' * (col - 1)}"
                f"::std::is_member_function_pointer_v<{signature}>, "
                f"{_quote(f'cannot layer {key}: not a non-static member function of a class')});\n"
                f"{_RESET}\n"
            )
        out.append("namespace {\n\n")
        entries: list[tuple[str, str]] = []
        base_entry = "nullptr"
        for function in ([base] if base is not None else []) + partials:
            generated = function.generated_name
            if first.owner is None:
                text = self.rewritten(
                    function,
                    name=generated,
                    parameter=parameter,
                    end=function.end,
                    strip_defaults=True,
                )
                out.append(self.placed(function, text))
                entry = f"&{generated}"
            else:
                tag = f"contextros_tag_{generated}"
                out.append(
                    f"struct {tag} {{\n  using result = ::contextros::ResultOf<{signature}>;\n}};\n"
                    "}  // namespace\n"
                )
                text = self.rewritten(
                    function,
                    name=f"contextros_impl<{tag}>",
                    parameter=parameter,
                    end=function.end,
                    strip_defaults=True,
                    strip_exception_specs=True,
                )
                out.append(self.placed(function, text, prefix="template <>"))
                out.append("namespace {\n")
                entry = f"&::contextros::MethodThunk<{tag}, {signature}>::call"
            out.append("\n")
            if function.layer is None:
                base_entry = entry
            else:
                entries.append((function.layer, entry))
        table = ",\n".join(f"     {{{_quote(layer)}, {entry}}}" for layer, entry in entries)
        out.append(
            f"::contextros::LayeredOf<{signature}> contextros_{stem}{{\n"
            f"    {_quote(key)},\n    {base_entry},\n    {{\n{table}}}}};\n\n}}  // namespace\n\n"
        )
        out.append(self.dispatch(first, functions, stem))
        return "".join(out)

    def dispatch(self, first: Function, functions: list[CppFunction], stem: str) -> str:
        chosen = self.dispatch_source(functions)
        if any(name is None for name in chosen.parameter_names):
            self.sink.error(
                f"the dispatch function of {chosen.key} needs parameter names: name every "
                "parameter in at least one implementation",
                chosen.at.line,
                chosen.at.col,
            )
        arguments = ["this" if first.owner is not None else "nullptr"]
        arguments += [
            f"static_cast<decltype({n})&&>({n})" for n in chosen.parameter_names if n is not None
        ]
        head = self.rewritten(
            chosen, name=None, parameter=None, end=chosen.declarator_end, strip_defaults=True
        )
        body = f" {{ return contextros_{stem}.invoke({', '.join(arguments)}); }}"
        return self.placed(chosen, head + body)
