"""The layer-description language: `.layers` files, their checker and their pre-compiler.

A layer file states the contexts explicitly and groups the context-dependent methods;
the pre-compiler turns it into an ordinary Python module (one function per layer and
method, one dispatch function per method) registered with the COP core. Never imports
ROS. The language is described in docs/language.md.

Names are imported lazily (PEP 562), each from its module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from contextros._exports import lazy_exports

if TYPE_CHECKING:
    from contextros.language.checker import check, check_file, check_source
    from contextros.language.compiler import CompiledLayers, compile_file, compile_source
    from contextros.language.diagnostics import (
        Diagnostic,
        LayerLanguageError,
        LayerSyntaxError,
        LayerTargetError,
        Severity,
    )
    from contextros.language.loader import (
        LayerInteractionWarning,
        install_import_hook,
        load,
        uninstall_import_hook,
    )
    from contextros.language.ordering import activation_order
    from contextros.language.parser import parse

_LAZY = {
    "check": "contextros.language.checker",
    "check_file": "contextros.language.checker",
    "check_source": "contextros.language.checker",
    "CompiledLayers": "contextros.language.compiler",
    "compile_file": "contextros.language.compiler",
    "compile_source": "contextros.language.compiler",
    "Diagnostic": "contextros.language.diagnostics",
    "LayerLanguageError": "contextros.language.diagnostics",
    "LayerSyntaxError": "contextros.language.diagnostics",
    "LayerTargetError": "contextros.language.diagnostics",
    "Severity": "contextros.language.diagnostics",
    "LayerInteractionWarning": "contextros.language.loader",
    "install_import_hook": "contextros.language.loader",
    "load": "contextros.language.loader",
    "uninstall_import_hook": "contextros.language.loader",
    "activation_order": "contextros.language.ordering",
    "parse": "contextros.language.parser",
}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())


__all__ = [
    "CompiledLayers",
    "Diagnostic",
    "LayerInteractionWarning",
    "LayerLanguageError",
    "LayerSyntaxError",
    "LayerTargetError",
    "Severity",
    "activation_order",
    "check",
    "check_file",
    "check_source",
    "compile_file",
    "compile_source",
    "install_import_hook",
    "load",
    "parse",
    "uninstall_import_hook",
]
