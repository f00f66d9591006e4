"""`Layer`: a named context that groups partial methods across classes and nodes."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from contextros.core.registry import Registry
from contextros.errors import LayerDefinitionError

Hook = Callable[[], object]


def _names(
    value: Iterable[Layer | str] | Layer | str, *, layer: str, relation: str
) -> frozenset[str]:
    items: Iterable[Layer | str] = [value] if isinstance(value, (Layer, str)) else value
    names = set()
    for item in items:
        name = item.name if isinstance(item, Layer) else item
        if not isinstance(name, str) or not name.isidentifier():
            raise LayerDefinitionError(
                f"layer {layer!r}: {relation} names {item!r}, which is not a layer or a layer name"
            )
        if name == layer:
            raise LayerDefinitionError(f"layer {layer!r} cannot {relation} itself")
        names.add(name)
    return frozenset(names)


class Layer:
    """A context (Indoor, Outdoor, LowBattery...) with its relations and hooks.

    Layers are values: two layers with the same name are equal and hash alike, so a
    layer travels across processes as its name. Creating one registers it in the
    process; the latest definition of a name is the one relations and hooks are read
    from.

    Relations, all checked before any switch applies (a violation changes nothing):

    - ``excludes``: never active together with these layers (symmetric).
    - ``requires``: may only be active while these layers are active.
    - ``group``: an exclusive group; activating a member deactivates the other
      members in the same atomic switch.
    - ``after``: when both are active, this layer comes after (outside) those: its
      partials run first. The core composes by activation order and does not reorder;
      the Layer manager composes the system's active set in this order (participants
      announce it), and ``contextros.language.activation_order`` computes it locally.
    - ``implies``: these layers are active whenever this one is (a system's mode implying
      its parts'). The Layer manager activates them with it, transitively, and removes
      what it alone implied when it leaves (participants announce it); the core itself
      activates only what it is given, and checks nothing about ``implies``.

    Hooks take no arguments. On a switch, ``on_deactivate`` hooks of the leaving
    layers run first (newest layer first, while they are still active), then the new
    configuration is installed, then ``on_activate`` hooks of the arriving layers
    run (in activation order).
    """

    __slots__ = (
        "after",
        "description",
        "excludes",
        "group",
        "implies",
        "name",
        "on_activate",
        "on_deactivate",
        "requires",
    )

    name: str
    description: str
    excludes: frozenset[str]
    requires: frozenset[str]
    after: frozenset[str]
    implies: frozenset[str]
    group: str | None
    on_activate: Hook | None
    on_deactivate: Hook | None

    def __init__(
        self,
        name: str,
        *,
        description: str = "",
        excludes: Iterable[Layer | str] | Layer | str = (),
        requires: Iterable[Layer | str] | Layer | str = (),
        group: str | None = None,
        on_activate: Hook | None = None,
        on_deactivate: Hook | None = None,
        after: Iterable[Layer | str] | Layer | str = (),
        implies: Iterable[Layer | str] | Layer | str = (),
    ) -> None:
        if not isinstance(name, str) or not name.isidentifier():
            raise LayerDefinitionError(
                f"layer name {name!r} is not an identifier (it names generated functions)"
            )
        if group is not None and (not isinstance(group, str) or not group.isidentifier()):
            raise LayerDefinitionError(f"layer {name!r}: group {group!r} is not an identifier")
        for hook_name, hook in (("on_activate", on_activate), ("on_deactivate", on_deactivate)):
            if hook is not None and not callable(hook):
                raise LayerDefinitionError(f"layer {name!r}: {hook_name} is not callable")
        self.name = name
        self.description = description
        self.excludes = _names(excludes, layer=name, relation="exclude")
        self.requires = _names(requires, layer=name, relation="require")
        if self.excludes & self.requires:
            both = ", ".join(sorted(self.excludes & self.requires))
            raise LayerDefinitionError(f"layer {name!r} both requires and excludes {both}")
        self.after = _names(after, layer=name, relation="come after")
        self.implies = _names(implies, layer=name, relation="imply")
        if self.excludes & self.implies:
            both = ", ".join(sorted(self.excludes & self.implies))
            raise LayerDefinitionError(f"layer {name!r} both implies and excludes {both}")
        self.group = group
        self.on_activate = on_activate
        self.on_deactivate = on_deactivate
        DEFINITIONS.register(self)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Layer):
            return self.name == other.name
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self.name)

    def __repr__(self) -> str:
        return f"Layer({self.name!r})"

    def __str__(self) -> str:
        return self.name


# The current definition of each layer name in this process.
DEFINITIONS: Registry[Layer] = Registry()


def layer_named(name: str) -> Layer:
    """The registered layer called `name` (UnknownLayerError names the known ones)."""
    return DEFINITIONS.lookup(name)


def defined_layers() -> tuple[Layer, ...]:
    """Every layer defined in this process (the current definition of each name), by name."""
    return tuple(DEFINITIONS.lookup(name) for name in DEFINITIONS.names())


def resolve(layer: Layer | str) -> Layer:
    """A layer given as an object or a name, as its current definition."""
    if isinstance(layer, Layer):
        return DEFINITIONS.find(layer.name) or layer
    if isinstance(layer, str):
        return DEFINITIONS.lookup(layer)
    raise TypeError(f"expected a Layer or a layer name, got {layer!r}")
