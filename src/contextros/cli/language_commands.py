"""`contextros compile`, `check` and `import-modes`: the language part's subcommands."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from contextros.language.flavour_names import LANGUAGES  # the parser on use only


def register(commands: Any) -> None:
    """Add this part's subcommands to the `contextros` parser.

    Each subparser sets `run=callable(args) -> int` via set_defaults.
    """
    compile_parser = commands.add_parser(
        "compile",
        help="translate a layer file into a Python module or C++ source and header",
        description="Translate a layer description into readable code: one function per "
        "layer and method, one dispatch function per method. NAME.layers and NAME.py.layers "
        "are Python (a module NAME.py); NAME.cpp.layers is C++ (NAME.layers.cpp and "
        "NAME.layers.hpp).",
    )
    compile_parser.add_argument("file", metavar="FILE.layers", help="the layer file")
    compile_parser.add_argument(
        "-o",
        "--output",
        metavar="OUT",
        help="where to write the module or the C++ source (default: next to the layer file; "
        "'-' for stdout). A C++ header goes beside it, OUT with .hpp for .cpp",
    )
    compile_parser.add_argument(
        "--language",
        choices=LANGUAGES,
        help="the layer file's flavour (default: from its name, NAME.cpp.layers is C++)",
    )
    compile_parser.add_argument(
        "--no-header",
        action="store_true",
        help="C++: put the header part into the source instead of a separate header",
    )
    compile_parser.set_defaults(run=run_compile)

    check_parser = commands.add_parser(
        "check",
        help="report errors and layer interaction warnings in .layers files",
        description="Check layer files. Prints 'file:line:col: error|warning|note: message' "
        "with the line and a caret; exits 1 if any file has errors. Rules' fields are checked "
        "against the message types of their 'topic' declarations, as installed here.",
    )
    check_parser.add_argument(
        "files",
        metavar="FILE",
        nargs="+",
        help="layer files, or directories to search for *.layers files",
    )
    check_parser.add_argument(
        "--language",
        choices=LANGUAGES,
        help="the files' flavour (default: from each name, NAME.cpp.layers is C++)",
    )
    check_parser.add_argument(
        "--activation",
        nargs="+",
        metavar="LAYER",
        help="also warn where activating these layers in this order contradicts the "
        "declared 'after' orders (the order you would give `contextros activate`)",
    )
    check_parser.add_argument(
        "--together",
        action="store_true",
        help="check the files as one set, as `contextros manager --layers FILE...` loads them: "
        "also a rule name or a topic's type declared in two of them, and rules' fields "
        "against another file's topic declaration",
    )
    check_parser.set_defaults(run=run_check)

    import_parser = commands.add_parser(
        "import-modes",
        help="turn a system_modes model file into a layer file",
        description="Translate a system_modes model (systems, parts, modes with parameters "
        "and lifecycle states, rules) into a layer file that behaves the same: a layer per "
        "mode, a group per system or node, 'implies' for a system mode's parts "
        "(docs/ros-integration.md). What cannot be converted exactly is a warning on stderr "
        "and a comment in the output; an error (MODEL.yaml:line:col) writes nothing, exit 2.",
    )
    import_parser.add_argument("model", metavar="MODEL.yaml", help="the system_modes model")
    import_parser.add_argument(
        "-o", "--output", metavar="FILE", help="the layer file to write (default: stdout)"
    )
    import_parser.set_defaults(run=run_import_modes)


_KINDS = {".py": "a Python module", ".cpp": "C++ source", ".hpp": "a C++ header", ".h": "a header"}


def not_layers(path: Path, *, directories: bool = True) -> str:
    """Why `path` is not something to check ('' when it is a layer file, or with
    `directories` a directory holding some). The manager refuses its --layers files for the
    same reasons, and directories (`directories=False`: it takes layer files, docs/cli.md)."""
    if path.is_dir() and not directories:
        return "a directory, not a layer file (name its layer files: DIR/*.layers)"
    if path.is_dir():
        return "" if any(path.rglob("*.layers")) else "a directory with no *.layers file in it"
    if path.name.endswith(".layers"):
        return ""
    kind = _KINDS.get(path.suffix, f"a '{path.suffix}' file" if path.suffix else "a file")
    return f"{kind}, not a layer file (layer files end in .layers)"


def _layer_files(names: list[str]) -> list[Path]:
    found: list[Path] = []
    for name in names:
        path = Path(name)
        found.extend(sorted(path.rglob("*.layers")) if path.is_dir() else [path])
    return found


def run_check(args: argparse.Namespace) -> int:
    from contextros.language.checker import check_files  # imported here: a fast CLI start

    # Rules' fields are checked against the message types their `topic` declarations name,
    # as installed here (imported only when declared; never rclpy).
    from contextros.ros.message_types import installed_message_type

    errors = 0
    for name in args.files:
        problem = not_layers(Path(name))
        if problem:
            print(f"{name}: error: {problem}; nothing checked")
            errors += 1
    paths = _layer_files([n for n in args.files if not not_layers(Path(n))])
    for group in [paths] if args.together else [[path] for path in paths]:
        diagnostics = check_files(group, args.language, installed_message_type)
        for path in group if args.activation else ():
            if not any(d.is_error and d.path == str(path) for d in diagnostics):
                diagnostics += _activation_warnings(path, args.activation, args.language)
        for diagnostic in diagnostics:
            print(diagnostic.render())
            errors += diagnostic.is_error
    return 1 if errors else 0


def _activation_warnings(path: Path, activation: list[str], language: str | None) -> list[Any]:
    from contextros.language.checker import check_activation_order
    from contextros.language.flavours import parse_with_diagnostics, read_source

    source = read_source(path)  # readable: check_file found no error
    layer_file, _ = parse_with_diagnostics(source, str(path), language)
    return check_activation_order(layer_file, activation)


def _shown_path(source: Path) -> str:
    """How the compiled module names its source: by the bare file name, never as typed on
    the command line nor relative to the output, so that the module is the same whatever
    the working directory and `-o` (a file in any directory, or `-`)."""
    return source.name


def run_compile(args: argparse.Namespace) -> int:
    from contextros.language.compiler import compile_source
    from contextros.language.diagnostics import LayerSyntaxError
    from contextros.language.flavours import language_of, read_source, stem_of

    source_path = Path(args.file)
    try:
        source = read_source(source_path)
    except (OSError, UnicodeDecodeError) as error:
        print(f"{args.file}:1:1: error: cannot read the layer file: {error}", file=sys.stderr)
        return 1
    if language_of(source_path, args.language) == "cpp":
        return _compile_cpp(args, source)
    try:
        compiled = compile_source(source, args.file)  # diagnostics name the file as typed
    except LayerSyntaxError as error:
        print(error.render(), file=sys.stderr)
        return 1
    for warning in compiled.warnings:
        print(warning.render(), file=sys.stderr)
    default = source_path.with_name(f"{stem_of(source_path)}.py")
    output = None if args.output == "-" else Path(args.output or default)
    shown = _shown_path(source_path)
    if shown != args.file:
        compiled = compile_source(source, shown)
    if output is None:
        sys.stdout.write(compiled.text)
        return 0
    try:
        output.write_text(compiled.text, encoding="utf-8")
    except OSError as error:
        print(f"contextros compile: cannot write {output}: {error}", file=sys.stderr)
        return 1
    return 0


def _compile_cpp(args: argparse.Namespace, source: str) -> int:
    from contextros.language.cpp.generator import compile_cpp
    from contextros.language.diagnostics import LayerSyntaxError
    from contextros.language.flavours import stem_of

    source_path = Path(args.file)
    output = args.output or str(source_path.with_name(f"{stem_of(source_path)}.layers.cpp"))
    to_stdout = output == "-"
    try:
        compiled = compile_cpp(
            source,
            args.file,
            output=None if to_stdout else output,
            header=not (args.no_header or to_stdout),
        )
    except LayerSyntaxError as error:
        print(error.render(), file=sys.stderr)
        return 1
    for warning in compiled.warnings:
        print(warning.render(), file=sys.stderr)
    if to_stdout:
        sys.stdout.write(compiled.source)
        return 0
    files = [(Path(output), compiled.source)]
    if compiled.header is not None and compiled.header_name is not None:
        files.append((Path(output).with_name(compiled.header_name), compiled.header))
    for path, text in files:
        try:
            _write_if_changed(path, text)
        except OSError as error:
            print(f"contextros compile: cannot write {path}: {error}", file=sys.stderr)
            return 1
    return 0


def _write_if_changed(path: Path, text: str) -> None:
    """Leave an unchanged output untouched, so a build does not recompile what includes it."""
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except (OSError, UnicodeDecodeError):
        pass
    path.write_text(text, encoding="utf-8")


def run_import_modes(args: argparse.Namespace) -> int:
    from contextros.language.system_modes import ModesModelError, import_modes

    try:
        source = Path(args.model).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as error:
        print(f"{args.model}:1:1: error: cannot read the model: {error}", file=sys.stderr)
        return 2
    try:
        imported = import_modes(source, args.model)
    except ModesModelError as error:
        print(error.render(), file=sys.stderr)
        print("contextros import-modes: nothing written", file=sys.stderr)
        return 2
    except ImportError as error:
        print(f"contextros import-modes: reading YAML needs PyYAML ({error})", file=sys.stderr)
        return 2
    for warning in imported.warnings:
        print(warning.render(), file=sys.stderr)
    if args.output in (None, "-"):
        sys.stdout.write(imported.text)
        return 0
    try:
        Path(args.output).write_text(imported.text, encoding="utf-8")
    except OSError as error:
        print(f"contextros import-modes: cannot write {args.output}: {error}", file=sys.stderr)
        return 1
    return 0
