"""The COP core: layers, layered functions, activation. Never imports ROS."""

from contextros.core.activation import (
    activate,
    activated,
    active_layers,
    critical,
    current_epoch,
    deactivate,
    deactivated,
    in_critical_section,
    set_active,
    subscribe,
    switch,
)
from contextros.core.layer import Layer, defined_layers, layer_named
from contextros.core.layered import LayeredFunction, layered, layered_function_of
from contextros.core.linking import proceed
from contextros.core.runtime import SwitchEvent, SwitchResult

__all__ = [
    "Layer",
    "LayeredFunction",
    "SwitchEvent",
    "SwitchResult",
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
    "layered_function_of",
    "proceed",
    "set_active",
    "subscribe",
    "switch",
]
