"""`contextros compile` and `contextros check`: the language part's subcommands."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from contextros.language.checker import check_file
from contextros.language.compiler import compile_source
from contextros.language.diagnostics import LayerSyntaxError


def register(commands: Any) -> None:
    """Add this part's subcommands to the `contextros` parser.

    Each subparser sets `run=callable(args) -> int` via set_defaults.
    """
    compile_parser = commands.add_parser(
        "compile",
        help="translate a .layers file into a Python module",
        description="Translate a layer description into a readable Python module: one "
        "function per layer and method, one dispatch function per method.",
    )
    compile_parser.add_argument("file", metavar="FILE.layers", help="the layer file")
    compile_parser.add_argument(
        "-o",
        "--output",
        metavar="OUT.py",
        help="where to write the module (default: FILE.py next to FILE.layers; '-' for stdout)",
    )
    compile_parser.set_defaults(run=run_compile)

    check_parser = commands.add_parser(
        "check",
        help="report errors and layer interaction warnings in .layers files",
        description="Check layer files. Prints 'file:line:col: error|warning: message' with "
        "the line and a caret; exits 1 if any file has errors.",
    )
    check_parser.add_argument(
        "files",
        metavar="FILE",
        nargs="+",
        help="layer files, or directories to search for *.layers files",
    )
    check_parser.set_defaults(run=run_check)


def _layer_files(names: list[str]) -> list[Path]:
    found: list[Path] = []
    for name in names:
        path = Path(name)
        found.extend(sorted(path.rglob("*.layers")) if path.is_dir() else [path])
    return found


def run_check(args: argparse.Namespace) -> int:
    errors = 0
    for path in _layer_files(args.files):
        for diagnostic in check_file(path):
            print(diagnostic.render())
            errors += diagnostic.is_error
    return 1 if errors else 0


def run_compile(args: argparse.Namespace) -> int:
    source_path = Path(args.file)
    try:
        source = source_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        print(f"{args.file}:1:1: error: cannot read the layer file: {error}", file=sys.stderr)
        return 1
    try:
        compiled = compile_source(source, args.file)
    except LayerSyntaxError as error:
        print(error.render(), file=sys.stderr)
        return 1
    for warning in compiled.warnings:
        print(warning.render(), file=sys.stderr)
    if args.output == "-":
        sys.stdout.write(compiled.text)
        return 0
    output = Path(args.output) if args.output else source_path.with_suffix(".py")
    try:
        output.write_text(compiled.text, encoding="utf-8")
    except OSError as error:
        print(f"contextros compile: cannot write {output}: {error}", file=sys.stderr)
        return 1
    return 0
