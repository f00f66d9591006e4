"""The process-wide table of defined layers, by name.

Layers are values (equal by name), so the table is what gives a name its current
definition: relations and hooks are always read from here. A later definition of a
name replaces the earlier one, which keeps module reloads and recompiled layer files
working.

The table holds anything named (`Layer` keeps the one instance, `contextros.core.layer.
DEFINITIONS`), so this module depends on no other module of the core.
"""

from __future__ import annotations

import threading
from typing import Generic, Protocol, TypeVar

from contextros.errors import UnknownLayerError


class Named(Protocol):
    @property
    def name(self) -> str: ...


N = TypeVar("N", bound=Named)


class Registry(Generic[N]):
    """Definitions by name; the latest definition of a name wins."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._items: dict[str, N] = {}

    def register(self, item: N) -> None:
        with self._lock:
            self._items[item.name] = item

    def unregister(self, name: str) -> None:
        with self._lock:
            self._items.pop(name, None)

    def lookup(self, name: str) -> N:
        """The current definition of `name`; UnknownLayerError when nobody defined it."""
        try:
            return self._items[name]
        except KeyError:
            raise UnknownLayerError(name, tuple(sorted(self._items))) from None

    def find(self, name: str) -> N | None:
        return self._items.get(name)

    def names(self) -> tuple[str, ...]:
        return tuple(sorted(self._items))
