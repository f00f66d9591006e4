"""`contextros import-modes`: a system_modes model file as a layer file that behaves the same.

    imported = import_modes(Path("drone_modes.yaml").read_text(), "drone_modes.yaml")
    imported.text       # the layer file (Python flavour)
    imported.warnings   # what is not converted exactly (diagnostics with line and column)

A malformed model raises `ModesModelError` with every problem at MODEL.yaml:line:col.
The model's reading is `model`, the mapping onto layers `translation` (its docstring says
how each construct maps); docs/ros-integration.md shows a model beside its layers.
"""

from __future__ import annotations

from dataclasses import dataclass

from contextros.language.diagnostics import (
    Diagnostic,
    DiagnosticSink,
    LayerLanguageError,
    sorted_diagnostics,
)
from contextros.language.system_modes.model import read_model
from contextros.language.system_modes.translation import translate


class ModesModelError(LayerLanguageError):
    """A system_modes model file is malformed or cannot be converted; nothing was written."""


@dataclass(frozen=True)
class ImportedModes:
    text: str
    warnings: tuple[Diagnostic, ...]


def import_modes(source: str, path: str = "<model>") -> ImportedModes:
    """The layer file for the system_modes model `source` (named `path` in diagnostics)."""
    sink = DiagnosticSink(path, source, syntax=True)
    model = read_model(source, sink)
    text = "" if sink.has_errors else translate(model, sink, path.rsplit("/", 1)[-1])
    found = sorted_diagnostics(sink.items)
    if sink.has_errors:
        raise ModesModelError(found)
    return ImportedModes(text, tuple(found))


__all__ = ["ImportedModes", "ModesModelError", "import_modes"]
