"""The public activation API: decisive, scoped and atomic switches, critical sections.

Decisive switches (`activate`, `deactivate`, `switch`, `set_active`) change the
process-wide configuration, as a ROS node following the Layer manager needs. Scoped
ones (`activated`, `deactivated`) hold only for the enclosed block, in the current
thread or asyncio task. Every switch is validated against the layers' relations
before anything changes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import AbstractContextManager, contextmanager

from contextros.core.configuration import Configuration, plan, validate
from contextros.core.layer import Layer, resolve
from contextros.core.runtime import RUNTIME, SwitchEvent, SwitchResult

LayerLike = Layer | str


def _resolve_all(layers: Iterable[LayerLike]) -> tuple[Layer, ...]:
    if isinstance(layers, (str, Layer)):
        layers = [layers]
    return tuple(resolve(layer) for layer in layers)


def activate(*layers: LayerLike) -> SwitchResult:
    """Activate `layers` process-wide (newest outermost). See `switch`."""
    return switch(activate=layers)


def deactivate(*layers: LayerLike) -> SwitchResult:
    """Deactivate `layers` process-wide. See `switch`."""
    return switch(deactivate=layers)


def switch(
    activate: Iterable[LayerLike] = (), deactivate: Iterable[LayerLike] = ()
) -> SwitchResult:
    """Deactivate, then activate, as one atomic transition.

    The resulting configuration is validated as a whole; a RelationError naming the
    layers leaves everything unchanged. Inside a critical section the switch is
    deferred and the returned result settles when the section ends.
    """
    on, off = _resolve_all(activate), _resolve_all(deactivate)
    return RUNTIME.request(lambda current: plan(current, on, off))


def set_active(layers: Iterable[LayerLike]) -> SwitchResult:
    """Make the decisive configuration exactly `layers`, in this (activation) order."""
    wanted = _resolve_all(layers)

    def exactly(current: Configuration) -> Configuration:
        validate(wanted)
        return wanted

    return RUNTIME.request(exactly)


def active_layers() -> Configuration:
    """The layers active for the caller (decisive plus its scopes), oldest first."""
    return RUNTIME.effective()


def in_critical_section() -> bool:
    """Whether a critical section is open somewhere in the process (switches are deferred)."""
    return RUNTIME.in_critical_section


def current_epoch() -> int:
    """How many decisive switches have applied in this process."""
    return RUNTIME.epoch


@contextmanager
def _scoped(steps: tuple[tuple[bool, Layer], ...]) -> Iterator[Configuration]:
    scope = RUNTIME.enter_scope(steps)
    token = RUNTIME.scope.set(scope)
    configuration = scope.configuration()
    del scope
    try:
        yield configuration
    finally:
        RUNTIME.scope.reset(token)
        RUNTIME.leave_scope()


def activated(*layers: LayerLike) -> AbstractContextManager[Configuration]:
    """Activate `layers` for the enclosed block only, in this thread or asyncio task.

    Tasks and threads started inside with a copied context see the layers too, for as
    long as they run. Relations are checked on entry.
    """
    return _scoped(tuple((True, layer) for layer in _resolve_all(layers)))


def deactivated(*layers: LayerLike) -> AbstractContextManager[Configuration]:
    """Deactivate `layers` for the enclosed block only, in this thread or asyncio task."""
    return _scoped(tuple((False, layer) for layer in _resolve_all(layers)))


def critical() -> AbstractContextManager[None]:
    """A region during which no decisive switch applies.

    Switches requested meanwhile, from any thread, are queued and applied in request
    order when the last open critical section ends; their SwitchResults settle then.
    """
    return RUNTIME.critical()


def activate_for(target: object, *layers: LayerLike) -> Configuration:
    """Activate `layers` for one object, or class-wide for a class (its instances and its
    subclasses'), on top of the decisive configuration; returns the target's configuration.

    Composition order for a call on an object: decisive layers, then class-wide layers
    of its classes from the most general base to its own class, then the object's own,
    then the caller's `with activated/deactivated` scope; within each, the later step is
    outermost. Relations are checked against the result for every receiver the change
    affects (for a class: its subclasses and their objects with layers of their own);
    RelationError naming the receiver: no change. A later decisive switch is never refused
    for a receiver: its levels that conflict with it are suspended (docs/core.md).
    Only layered methods, classmethods and property getters of the classes concerned take
    the per-receiver path; free functions and staticmethods have no receiver.
    """
    return _change_for(target, tuple((True, layer) for layer in _resolve_all(layers)))


def deactivate_for(target: object, *layers: LayerLike) -> Configuration:
    """Deactivate `layers` for one object (or class-wide for a class), even while they are
    decisively active; see `activate_for`."""
    return _change_for(target, tuple((False, layer) for layer in _resolve_all(layers)))


def reset_for(target: object, *layers: LayerLike) -> Configuration:
    """Forget `target`'s own activations and deactivations of `layers` (all when none are
    named): it follows its class and the decisive configuration again."""
    with RUNTIME.lock:
        RUNTIME.receivers.change(target, (), _resolve_all(layers))
        return layers_for(target)


def layers_for(target: object) -> Configuration:
    """The layers a call on `target` (an object, or a class for its classmethods) sees from
    here: decisive, class-wide, per-object and the caller's scope, oldest first."""
    return RUNTIME.effective(target)


def _change_for(target: object, steps: tuple[tuple[bool, Layer], ...]) -> Configuration:
    with RUNTIME.lock:
        RUNTIME.receivers.change(target, steps, None)
        return layers_for(target)


def remove_layer(layer: LayerLike) -> tuple[str, ...]:
    """Remove a layer at run time: deactivate it if it is decisively active (validated:
    a RelationError changes nothing), drop its partial methods from every layered
    function (each is rewired at once) and forget its definition. Returns the qualified
    names of the functions it refined. Scopes and receivers (`activate_for`) still naming it
    see a transparent layer."""
    return RUNTIME.remove_layer(resolve(layer))


def subscribe(observer: Callable[[SwitchEvent], object]) -> Callable[[], None]:
    """Call `observer(event)` after every applied decisive switch; returns unsubscribe."""
    return RUNTIME.subscribe(observer)


__all__ = [
    "activate",
    "activate_for",
    "activated",
    "active_layers",
    "critical",
    "current_epoch",
    "deactivate",
    "deactivate_for",
    "deactivated",
    "in_critical_section",
    "layers_for",
    "remove_layer",
    "reset_for",
    "set_active",
    "subscribe",
    "switch",
]
