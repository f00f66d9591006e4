"""The flavours of the layer language and which one a file is written in.

Both flavours share the syntax tree, the checker and the diagnostics; each has its own
parser and back end. A file's flavour comes from its inner suffix: `NAME.cpp.layers` is
C++, `NAME.layers` and `NAME.py.layers` are Python (`--language` overrides).
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from contextros.language.diagnostics import Diagnostic, DiagnosticSink
from contextros.language.flavour_names import LANGUAGES
from contextros.language.syntax import LayerFile

SUFFIX = ".layers"
# The inner suffix naming a file's flavour: NAME.py.layers, NAME.cpp.layers (.cc, .cxx).
FLAVOUR_SUFFIXES = {".py": "python", ".cpp": "cpp", ".cc": "cpp", ".cxx": "cpp"}


def language_of(path: str | os.PathLike[str], language: str | None = None) -> str:
    """The flavour of the layer file at `path`, unless `language` names one."""
    if language is not None:
        if language not in LANGUAGES:
            raise ValueError(f"unknown layer language {language!r} (known: {', '.join(LANGUAGES)})")
        return language
    name = os.path.basename(os.fspath(path))
    cpp = tuple(inner + SUFFIX for inner, flavour in FLAVOUR_SUFFIXES.items() if flavour == "cpp")
    return "cpp" if name.endswith(cpp) else "python"


def decode_source(data: bytes) -> str:
    """A layer file's text from its bytes: UTF-8, with or without a byte order mark (which
    some editors write; it is not part of the text, so it cannot be a syntax error at 1:1)."""
    return data.decode("utf-8-sig")


def read_source(path: str | os.PathLike[str]) -> str:
    """The text of the layer file at `path` (see `decode_source`); raises OSError or
    UnicodeDecodeError."""
    with open(path, "rb") as stream:
        return decode_source(stream.read())


def unreadable(path: str | os.PathLike[str], error: Exception) -> list[Diagnostic]:
    """The error for a layer file that cannot be read, located at 1:1."""
    sink = DiagnosticSink(os.fspath(path), "")
    sink.error(f"cannot read the layer file: {error}", 1, 1)
    return sink.items


def stem_of(path: str | os.PathLike[str]) -> str:
    """The name of a layer file without `.layers` and its flavour's suffix: `robot` for
    `robot.layers`, `robot.py.layers` and `robot.cpp.layers`; what outputs are named after
    (`robot.py`; `robot.layers.cpp`) and, in Python, the module's name. A file not named
    `*.layers` gives its name without its last suffix."""
    name = os.path.basename(os.fspath(path))
    if not name.endswith(SUFFIX):
        return os.path.splitext(name)[0] or name
    stem = name.removesuffix(SUFFIX)
    base, inner = os.path.splitext(stem)
    if inner in FLAVOUR_SUFFIXES and base:
        stem = base
    return stem or name


def parse_with_diagnostics(
    source: str, path: str, language: str | None = None
) -> tuple[LayerFile, list[Diagnostic]]:
    """Parse in the file's flavour; all syntax diagnostics, never raised."""
    if language_of(path, language) == "cpp":
        from contextros.language.cpp.parser import parse_with_diagnostics as parse_cpp

        return parse_cpp(source, path)
    from contextros.language.parser import parse_with_diagnostics as parse_python

    return parse_python(source, path)


def parse_files(
    paths: Iterable[str | os.PathLike[str]], language: str | None = None
) -> tuple[list[tuple[str, str, LayerFile]], list[Diagnostic]]:
    """Read and parse layer files, each in its flavour: (name, source, syntax tree) of each
    file read, and the errors (a file that cannot be read is one, located at 1:1)."""
    parsed: list[tuple[str, str, LayerFile]] = []
    errors: list[Diagnostic] = []
    for path in paths:
        name = os.fspath(path)
        try:
            source = read_source(name)
        except (OSError, UnicodeDecodeError) as error:
            errors += unreadable(name, error)
            continue
        layer_file, found = parse_with_diagnostics(source, name, language)
        errors += [d for d in found if d.is_error]
        parsed.append((name, source, layer_file))
    return parsed, errors
