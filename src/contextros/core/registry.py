"""The process-wide table of defined layers, by name.

Layers are values (equal by name), so the table is what gives a name its current
definition: relations and hooks are always read from here. A later definition of a
name replaces the earlier one, which keeps module reloads and recompiled layer files
working.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

from contextros.errors import UnknownLayerError

if TYPE_CHECKING:
    from contextros.core.layer import Layer

_lock = threading.Lock()
_layers: dict[str, Layer] = {}


def register(layer: Layer) -> None:
    with _lock:
        _layers[layer.name] = layer


def unregister(name: str) -> None:
    with _lock:
        _layers.pop(name, None)


def lookup(name: str) -> Layer:
    """The current definition of `name`; UnknownLayerError when nobody defined it."""
    try:
        return _layers[name]
    except KeyError:
        raise UnknownLayerError(name, tuple(sorted(_layers))) from None


def find(name: str) -> Layer | None:
    return _layers.get(name)


def names() -> tuple[str, ...]:
    return tuple(sorted(_layers))
