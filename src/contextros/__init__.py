"""ContextROS: context-oriented programming for ROS 2.

The names here are the COP core and `load` for layer files (no ROS needed). The layer
language lives in `contextros.language`, the distributed Layer manager in `contextros.ros`.

Names are imported lazily (PEP 562): `import contextros` loads only the error classes, and
the core or the language is imported on the first use of one of their names, so that the
command-line tools start fast.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from contextros._exports import lazy_exports
from contextros.errors import (
    DispatchError,
    HookError,
    LayerDefinitionError,
    LayerError,
    NoImplementationError,
    ProceedError,
    RelationError,
    UnknownLayerError,
)

if TYPE_CHECKING:
    from contextros.core import (
        Layer,
        SwitchEvent,
        SwitchResult,
        activate,
        activate_for,
        activated,
        active_layers,
        critical,
        current_epoch,
        deactivate,
        deactivate_for,
        deactivated,
        defined_layers,
        in_critical_section,
        layer_named,
        layered,
        layers_for,
        proceed,
        remove_layer,
        reset_for,
        set_active,
        subscribe,
        switch,
    )
    from contextros.language import load

__version__ = "0.1.0"

_LAZY = {
    name: "contextros.core"
    for name in (
        "Layer",
        "SwitchEvent",
        "SwitchResult",
        "activate",
        "activate_for",
        "activated",
        "active_layers",
        "critical",
        "current_epoch",
        "deactivate",
        "deactivate_for",
        "deactivated",
        "defined_layers",
        "in_critical_section",
        "layer_named",
        "layered",
        "layers_for",
        "proceed",
        "remove_layer",
        "reset_for",
        "set_active",
        "subscribe",
        "switch",
    )
} | {"load": "contextros.language"}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())


__all__ = [
    "DispatchError",
    "HookError",
    "Layer",
    "LayerDefinitionError",
    "LayerError",
    "NoImplementationError",
    "ProceedError",
    "RelationError",
    "SwitchEvent",
    "SwitchResult",
    "UnknownLayerError",
    "__version__",
    "activate",
    "activate_for",
    "activated",
    "active_layers",
    "critical",
    "current_epoch",
    "deactivate",
    "deactivate_for",
    "deactivated",
    "defined_layers",
    "in_critical_section",
    "layer_named",
    "layered",
    "layers_for",
    "load",
    "proceed",
    "remove_layer",
    "reset_for",
    "set_active",
    "subscribe",
    "switch",
]
