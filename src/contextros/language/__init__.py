"""The layer-description language: `.layers` files, their checker and their pre-compiler.

A layer file states the contexts explicitly and groups the context-dependent methods;
the pre-compiler turns it into an ordinary Python module (one function per layer and
method, one dispatch function per method) registered with the COP core. Never imports
ROS. The language is described in docs/language.md.
"""

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
