"""What `after` means at run time: the order in which to activate layers.

`layer Night after Outdoor:` declares that when both are active, Night was activated
after Outdoor: its implementations are outermost and their `proceed()` reaches
Outdoor's. The core composes by activation order, so the declaration becomes real by
activating in a compatible order, which `activation_order` computes for `set_active`.
"""

from __future__ import annotations

from collections.abc import Iterable
from types import ModuleType

from contextros.errors import RelationError


def activation_order(module: ModuleType, layers: Iterable[object]) -> list[str]:
    """`layers` (names or Layer objects) sorted so every declared `after` holds.

    Layers unrelated by `after` keep their given order. Pass the result to
    `contextros.set_active` to make the configuration exactly this.
    """
    names = [getattr(layer, "name", layer) for layer in layers]
    if not all(isinstance(name, str) for name in names):
        raise TypeError(f"expected layers or layer names, got {list(layers)!r}")
    wanted: list[str] = list(dict.fromkeys(str(name) for name in names))
    declared: tuple[tuple[str, str], ...] = getattr(module, "__layer_order__", ())
    # later -> the layers it must come after, restricted to the requested ones
    must_follow: dict[str, set[str]] = {name: set() for name in wanted}
    for later, earlier in declared:
        if later in must_follow and earlier in must_follow:
            must_follow[later].add(earlier)
    ordered: list[str] = []
    remaining = list(wanted)
    while remaining:
        ready = next((n for n in remaining if must_follow[n] <= set(ordered)), None)
        if ready is None:
            raise RelationError(
                f"the declared 'after' orders of {', '.join(remaining)} form a cycle",
                tuple(remaining),
            )
        ordered.append(ready)
        remaining.remove(ready)
    return ordered
