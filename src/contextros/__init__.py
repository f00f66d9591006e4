"""ContextROS: context-oriented programming for ROS 2.

The names here are the COP core and `load` for layer files (no ROS needed). The layer
language lives in `contextros.language`, the distributed Layer manager in `contextros.ros`.
"""

from contextros.core import (
    Layer,
    SwitchEvent,
    SwitchResult,
    activate,
    activated,
    active_layers,
    critical,
    current_epoch,
    deactivate,
    deactivated,
    defined_layers,
    in_critical_section,
    layer_named,
    layered,
    proceed,
    set_active,
    subscribe,
    switch,
)
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
from contextros.language import load

__version__ = "0.1.0"

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
    "activated",
    "active_layers",
    "critical",
    "current_epoch",
    "deactivate",
    "deactivated",
    "defined_layers",
    "in_critical_section",
    "layer_named",
    "layered",
    "load",
    "proceed",
    "set_active",
    "subscribe",
    "switch",
]
