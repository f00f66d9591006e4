"""Pure rules for configurations: which layers are active, in which order.

A configuration is a tuple of layers in activation order (oldest first); the last
one is outermost in every composed chain. These functions never change state: the
runtime asks them for the next configuration and installs it only if they agree.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from contextros.core.layer import DEFINITIONS, Layer
from contextros.errors import RelationError

Configuration = tuple[Layer, ...]


def _definition(layer: Layer) -> Layer:
    return DEFINITIONS.find(layer.name) or layer


def plan(
    current: Configuration, activate: Sequence[Layer], deactivate: Sequence[Layer]
) -> Configuration:
    """The configuration after deactivating, then activating, the given layers.

    Activating an active layer keeps its place; activating a member of an exclusive
    group drops the other members. The result is validated as a whole, so the
    intermediate steps may break relations.
    """
    both = set(activate) & set(deactivate)
    if both:
        names = ", ".join(sorted(layer.name for layer in both))
        raise RelationError(
            f"layer(s) {names} asked to be both activated and deactivated in one switch",
            tuple(sorted(layer.name for layer in both)),
        )
    _check_group_requests(activate)
    leaving = set(deactivate)
    layers = [layer for layer in current if layer not in leaving]
    for layer in activate:
        layers = _with(layers, layer)
    result = tuple(layers)
    validate(result)
    return result


def replay(current: Configuration, steps: Iterable[tuple[bool, Layer]]) -> Configuration:
    """Apply scoped (de)activations to `current` without validating (see activated())."""
    layers = list(current)
    for activating, layer in steps:
        if activating:
            layers = _with(layers, layer)
        elif layer in layers:
            layers.remove(layer)
    return tuple(layers)


def _with(layers: list[Layer], layer: Layer) -> list[Layer]:
    group = _definition(layer).group
    if group is not None:
        layers = [other for other in layers if other == layer or _definition(other).group != group]
    if layer not in layers:
        layers.append(layer)
    return layers


def _check_group_requests(activate: Sequence[Layer]) -> None:
    seen: dict[str, Layer] = {}
    for layer in activate:
        group = _definition(layer).group
        if group is None:
            continue
        other = seen.setdefault(group, layer)
        if other != layer:
            raise RelationError(
                f"layers {other.name} and {layer.name} are both in exclusive group {group!r}; "
                "activate only one of them",
                (other.name, layer.name),
            )


def validate(configuration: Configuration) -> None:
    """Raise RelationError naming the layers when `configuration` breaks a relation."""
    names = [layer.name for layer in configuration]
    if len(set(names)) != len(names):
        repeated = sorted({name for name in names if names.count(name) > 1})
        raise RelationError(f"layer(s) {', '.join(repeated)} listed twice", tuple(repeated))
    active = set(names)
    groups: dict[str, str] = {}
    for layer in configuration:
        definition = _definition(layer)
        for other in sorted(definition.excludes & active):
            raise RelationError(
                f"layers {layer.name} and {other} cannot be active together "
                f"({layer.name} excludes {other})",
                (layer.name, other),
            )
        for needed in sorted(definition.requires - active):
            raise RelationError(
                f"layer {layer.name} requires {needed}, which would not be active "
                f"(activate {needed} too, or deactivate {layer.name})",
                (layer.name, needed),
            )
        if definition.group is not None:
            other_name = groups.setdefault(definition.group, layer.name)
            if other_name != layer.name:
                raise RelationError(
                    f"layers {other_name} and {layer.name} are both in exclusive group "
                    f"{definition.group!r}",
                    (other_name, layer.name),
                )
