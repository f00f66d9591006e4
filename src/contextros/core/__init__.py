"""The COP core: layers, layered functions, activation. Never imports ROS."""

from contextros.core.activation import (
    activate,
    activate_for,
    activated,
    active_layers,
    critical,
    current_epoch,
    deactivate,
    deactivate_for,
    deactivated,
    in_critical_section,
    layers_for,
    remove_layer,
    reset_for,
    set_active,
    subscribe,
    switch,
)
from contextros.core.composition import DISPATCHER
from contextros.core.layer import Layer, defined_layers, layer_named
from contextros.core.layered import (
    LayeredFunction,
    LayeredProperty,
    layered,
    layered_function_of,
)
from contextros.core.linking import proceed
from contextros.core.runtime import SwitchEvent, SwitchResult

__all__ = [
    "DISPATCHER",
    "Layer",
    "LayeredFunction",
    "LayeredProperty",
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
    "layered_function_of",
    "layers_for",
    "proceed",
    "remove_layer",
    "reset_for",
    "set_active",
    "subscribe",
    "switch",
]
