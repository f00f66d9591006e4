"""The process-wide activation state: the decisive configuration, its epoch, scopes,
critical sections and observers.

One lock serialises switches; calls never take it. A switch composes every layered
function for the new configuration and installs the heads, then bumps the epoch and
tells observers, so a call runs either the old chain or the new one, never a mix.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

from contextros.core import configuration as rules
from contextros.core.composition import LayeredFunction, layered_function_of
from contextros.core.configuration import Configuration
from contextros.core.layer import DEFINITIONS, Layer
from contextros.errors import HookError, LayerDefinitionError, LayerError, RelationError

log = logging.getLogger("contextros")


@dataclass(frozen=True)
class SwitchEvent:
    """An applied decisive switch, as observers see it."""

    epoch: int
    old: Configuration
    new: Configuration

    @property
    def activated(self) -> Configuration:
        return tuple(layer for layer in self.new if layer not in self.old)

    @property
    def deactivated(self) -> Configuration:
        return tuple(layer for layer in self.old if layer not in self.new)


@dataclass(eq=False)
class SwitchResult:
    """What became of a requested switch.

    Outside critical sections a switch applies before the call returns (`applied`, with
    the new `epoch`; an unchanged configuration keeps the current epoch). Inside one it
    is `deferred`: `wait()` blocks until it was applied or rejected (`error`).
    """

    deferred: bool = False
    applied: bool = False
    epoch: int | None = None
    error: LayerError | None = None
    _done: threading.Event = field(default_factory=threading.Event, repr=False)

    def wait(self, timeout: float | None = None) -> bool:
        """True once the switch was applied; False if rejected or still pending."""
        self._done.wait(timeout)
        return self.applied

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def _settle(self, epoch: int | None, error: LayerError | None) -> None:
        self.applied = error is None
        self.epoch = epoch
        self.error = error
        self._done.set()


Plan = Callable[[Configuration], Configuration]


# The heads composed for one configuration, by layered function, with that configuration
# under the key _CONFIGURATION. A plain dict (a subclass would slow every call's subscript).
#
# Replaced as a whole on every decisive switch, never cleared: a head computed for an older
# configuration can only be stored in that configuration's table, so a thread racing a
# switch never leaves a stale head where the next call would find it.
_CONFIGURATION = object()
Heads = dict[object, Any]


def _heads(configuration: Configuration) -> Heads:
    return {_CONFIGURATION: configuration}


class _Scope:
    """The scoped (de)activations of one `with activated/deactivated` block and its parents.

    Alive while any context (thread, task, copied context) can still see it; the
    runtime uses the live count to know whether calls must consult context variables.
    `heads` holds the configuration of this scope under the current decisive one and
    the heads composed for it; the runtime replaces it on every decisive switch.
    """

    __slots__ = ("__weakref__", "_runtime", "heads", "steps")

    def __init__(self, runtime: Runtime, steps: tuple[tuple[bool, Layer], ...]) -> None:
        self._runtime = runtime
        self.steps = steps
        self.heads = _heads(rules.replay(runtime.active, steps))

    def refresh(self, active: Configuration) -> None:
        self.heads = _heads(rules.replay(active, self.steps))

    def configuration(self) -> Configuration:
        configuration: Configuration = self.heads[_CONFIGURATION]
        return configuration

    def head(self, function: LayeredFunction) -> Callable[..., Any]:
        heads = self.heads  # one snapshot: configuration and table belong together
        head = heads.get(function)
        if head is None:
            head = heads[function] = function.head_for(heads[_CONFIGURATION])
        return head

    def __del__(self) -> None:
        self._runtime._scope_released()


Steps = tuple[tuple[bool, Layer], ...]
# The key of an object's own level among its levels (a class-wide level's key is its class).
_OWN = "own layers"
Levels = list[tuple[object, Steps]]


def _configure(
    active: Configuration, levels: Levels
) -> tuple[Configuration, dict[object, RelationError]]:
    """Replay `levels` (class-wide ones from the most general class, then the object's
    own) on the decisive configuration `active`. A level whose result breaks a relation
    is suspended (skipped: the decisive configuration wins) and reported by key."""
    configuration = active
    suspended: dict[object, RelationError] = {}
    for key, steps in levels:
        candidate = rules.replay(configuration, steps)
        try:
            rules.validate(candidate)
        except RelationError as error:
            suspended[key] = error
        else:
            configuration = candidate
    return configuration, suspended


class _Receiver:
    """The configuration of one receiver (a class, class-wide; or an object): its levels
    replayed on the decisive configuration, and the heads composed for that."""

    __slots__ = ("heads",)

    def __init__(self, configuration: Configuration) -> None:
        self.heads = _heads(configuration)

    def configuration(self) -> Configuration:
        configuration: Configuration = self.heads[_CONFIGURATION]
        return configuration

    def head(self, function: LayeredFunction, scope: _Scope | None) -> Callable[..., Any]:
        heads = self.heads  # one snapshot, as in _Scope.head
        key: object = function if scope is None else (function, scope.steps)
        head = heads.get(key)
        if head is None:
            configuration = heads[_CONFIGURATION]
            if scope is not None:
                configuration = rules.replay(configuration, scope.steps)
            head = heads[key] = function.head_for(configuration)
        return head


class _ByClass(dict):  # type: ignore[type-arg]
    """Receiver per concrete class, computed on first use from the class-wide steps of
    its MRO (None: no class-wide layers); emptied whenever those or the decisive
    configuration change."""

    def __init__(self, receivers: Receivers) -> None:
        super().__init__()
        self._receivers = receivers

    def __missing__(self, cls: type) -> _Receiver | None:
        receivers = self._receivers
        levels = receivers.class_levels(cls)
        found = _Receiver(_configure(receivers.runtime.active, levels)[0]) if levels else None
        self[cls] = found
        return found


class Receivers:
    """Per-object and class-wide activation.

    Order of composition for a call on a receiver: the decisive configuration; then the
    class-wide steps of its classes, from the most general base class to its own class;
    then the object's own steps; then the caller's scoped steps (`with activated`). A
    layered function defined in a class with such layers (or in one of its bases or
    subclasses) takes a per-receiver path; every other function keeps its direct path.

    Each class's steps and an object's own steps form a level. A change through
    `activate_for`/`deactivate_for`/`reset_for` is validated for every receiver it
    affects; a decisive switch is never refused for a receiver: a level that breaks a
    relation with the new decisive configuration is suspended (skipped) while it does.
    """

    def __init__(self, runtime: Runtime) -> None:
        self.runtime = runtime
        self._class_steps: dict[type, Steps] = {}
        self._object_steps: dict[int, Steps] = {}
        self._object_types: dict[int, type] = {}
        # Forgets the object when it goes (detached when its own layers are forgotten).
        self._finalizers: dict[int, weakref.finalize[Any, Any]] = {}
        self.objects: dict[int, _Receiver] = {}
        self.classes = _ByClass(self)
        self._functions: set[LayeredFunction] = set()
        # (receiver, level) pairs suspended after the last decisive switch, for the log.
        self._suspended: set[tuple[object, object]] = set()
        # The receiver whose own or class-wide layers changed last (weakly): the C
        # dispatchers expect its heads (`LayeredFunction._install_dispatcher`).
        self._latest: Callable[[], object] = _nothing

    # -- queries ---------------------------------------------------------------------------

    def class_levels(self, cls: type, override: tuple[type, Steps] | None = None) -> Levels:
        """The class-wide levels of `cls`'s MRO, most general first (`override`: one
        class's steps as they would be after a change)."""
        levels: Levels = []
        for klass in reversed(getattr(cls, "__mro__", ())):
            if override is not None and klass is override[0]:
                steps = override[1]
            else:
                steps = self._class_steps.get(klass, ())
            if steps:
                levels.append((klass, steps))
        return levels

    def _objects(self) -> list[tuple[int, type, Steps]]:
        """(id, class, own steps) of the objects with layers of their own, from copies:
        a collected object's finalizer may run (on this thread, under the lock) while
        the caller iterates."""
        steps, types = self._object_steps.copy(), self._object_types.copy()
        return [(key, types[key], own) for key, own in steps.items() if key in types]

    def _object(self, key: int) -> object:
        finalizer = self._finalizers.get(key)
        found = finalizer.peek() if finalizer is not None else None
        return found[0] if found is not None else None

    def _object_levels(
        self, cls: type, own: Steps, override: tuple[type, Steps] | None = None
    ) -> Levels:
        return [*self.class_levels(cls, override), (_OWN, own)]

    def of(self, receiver: object) -> _Receiver | None:
        found = self.objects.get(id(receiver))
        if found is None:
            found = self.classes[receiver if isinstance(receiver, type) else type(receiver)]
        return found

    def latest(self) -> object:
        """The receiver whose layers changed last, if it is still there."""
        return self._latest()

    def own_steps(self, target: object) -> Steps:
        if isinstance(target, type):
            return self._class_steps.get(target, ())
        return self._object_steps.get(id(target), ())

    # -- changes (under the runtime's lock) -------------------------------------------------

    def change(self, target: object, steps: Steps, forget: tuple[Layer, ...] | None) -> None:
        """Add `steps` to `target`'s own (a later step for a layer replaces an earlier one),
        or with `forget` drop its steps for those layers (all when empty). Validated for
        every receiver the change affects: a RelationError leaves everything unchanged."""
        current = self.own_steps(target)
        if forget is not None:
            dropped = set(forget)
            new = tuple(step for step in current if dropped and step[1] not in dropped)
        else:
            named = {layer for _, layer in steps}
            new = tuple(step for step in current if step[1] not in named) + steps
        if isinstance(target, type):
            self._check_class_change(target, new, adding=forget is None)
            if new:
                self._class_steps[target] = new
            else:
                self._class_steps.pop(target, None)
            classes = [target, *_subclasses(target)]
        else:
            key = id(target)
            cls = type(target)
            levels = self.class_levels(cls)
            self._check(
                target,
                _OWN,
                [*levels, (_OWN, current)] if current else levels,
                [*levels, (_OWN, new)] if new else levels,
                adding=forget is None,
            )
            if new:
                if key not in self._finalizers:
                    try:
                        finalizer = weakref.finalize(target, self._object_gone, key)
                    except TypeError:
                        raise LayerDefinitionError(
                            f"per-object activation needs an object that supports weak "
                            f"references; {cls.__name__} has __slots__ without "
                            "'__weakref__' (or is a built-in type): activate for its class"
                        ) from None
                    finalizer.atexit = False
                    self._finalizers[key] = finalizer
                self._object_steps[key] = new
                self._object_types[key] = cls
            else:
                self._forget_object(key)
            classes = [cls]
        try:
            self._latest = weakref.ref(target)
        except TypeError:  # a forgotten object without weak references
            self._latest = _nothing
        self._rebuild()
        if new:
            self._mark(classes)  # reinstalls every function on the per-receiver path
        else:
            self._reinstall()

    def _check_class_change(self, target: type, new: Steps, *, adding: bool) -> None:
        """Validate a class-wide change for the class, its subclasses and their objects
        with layers of their own."""
        override = (target, new)
        affected = [target, *_subclasses(target)]
        for cls in affected:
            self._check(
                cls, target, self.class_levels(cls), self.class_levels(cls, override), adding=adding
            )
        concerned = set(affected)
        for key, cls, own in self._objects():
            if cls in concerned:
                self._check(
                    self._object(key),
                    target,
                    self._object_levels(cls, own),
                    self._object_levels(cls, own, override),
                    adding=adding,
                )

    def _check(
        self, receiver: object, changed: object, before: Levels, after: Levels, *, adding: bool
    ) -> None:
        """Refuse a change that suspends a level of `receiver` that was not suspended, or
        that adds steps to a level (`changed`) that stays suspended."""
        active = self.runtime.active
        _, now = _configure(active, after)
        if not now:
            return
        _, earlier = _configure(active, before)
        for level, error in now.items():
            if level not in earlier or (adding and level is changed):
                raise RelationError(
                    f"{error}, for {_describe(receiver)} (its class-wide and own layers on "
                    "the decisive configuration); the change to "
                    f"{_describe_level(changed, receiver)} was refused, nothing changed",
                    error.layers,
                )

    def _forget_object(self, key: int) -> None:
        self._object_steps.pop(key, None)
        self._object_types.pop(key, None)
        finalizer = self._finalizers.pop(key, None)
        if finalizer is not None:
            finalizer.detach()  # a no-op once the object went

    def _object_gone(self, key: int) -> None:
        with self.runtime.lock:
            self._forget_object(key)
            # From the table the functions read (always the current one: every rebuild
            # is reinstalled), before the id can be reused by a new object.
            self.objects.pop(key, None)
            if not self._class_steps and not self._object_steps:
                self._unmark()

    def _rebuild(self) -> None:
        """New tables, never cleared ones: a call racing this change can only store what
        it computed into the old tables (as with the heads tables); the functions are reinstalled
        with the new ones right after (by the switch, `_mark` or `_reinstall`), so the
        tables the functions read are always `objects` and `classes`."""
        active = self.runtime.active
        present = self._objects()
        objects = {
            key: _Receiver(_configure(active, self._object_levels(cls, own))[0])
            for key, cls, own in present
        }
        self.objects = objects
        for key, _, _ in present:  # gone meanwhile (its finalizer ran on this thread)
            if key not in self._object_steps:
                objects.pop(key, None)
        self.classes = _ByClass(self)
        if not self._class_steps and not self._object_steps:
            self._unmark()

    def refresh(self, active: Configuration) -> None:
        """After a decisive switch (or changed partials): every receiver's configuration
        and heads for the new configuration (`layers_for` reads them too, so also for
        receivers whose classes have no layered methods)."""
        if self._functions or self._class_steps or self._object_steps:
            self._rebuild()
            self._log_suspended(active)

    def _log_suspended(self, active: Configuration) -> None:
        """Log each level a decisive switch suspends (once, until it applies again): a
        class's own level on the class (its subclasses and objects share it), an
        object's own level on the object."""
        suspended: set[tuple[object, object]] = set()
        receivers: list[tuple[object, object, Levels]] = [
            (cls, cls, self.class_levels(cls)) for cls in self._class_steps
        ]
        receivers += [
            (key, _OWN, self._object_levels(cls, own)) for key, cls, own in self._objects()
        ]
        for receiver, own, levels in receivers:
            error = _configure(active, levels)[1].get(own)
            if error is None:
                continue
            suspended.add((receiver, own))
            if (receiver, own) not in self._suspended:
                shown = self._object(receiver) if isinstance(receiver, int) else receiver
                log.warning(
                    "contextros: %s suspended while the decisive configuration breaks a "
                    "relation with them: %s",
                    _describe_level(own, shown),
                    error,
                )
        self._suspended = suspended

    def forget_all(self) -> None:
        self._class_steps.clear()
        self._object_steps.clear()
        self._object_types.clear()
        for finalizer in self._finalizers.values():
            finalizer.detach()
        self._finalizers.clear()
        self._suspended = set()
        self._rebuild()

    def _mark(self, classes: list[type]) -> None:
        seen: set[type] = set()
        for cls in classes:
            for klass in getattr(cls, "__mro__", (cls,)):
                if klass in seen or klass is object:
                    continue
                seen.add(klass)
                for value in vars(klass).values():
                    if isinstance(value, staticmethod):
                        continue  # no receiver: decisive and scoped layers only
                    owner = layered_function_of(value)
                    if owner is None:
                        continue
                    owner.receiver_kind = "class" if isinstance(value, classmethod) else "object"
                    self._functions.add(owner)
        for function in self._functions:
            self.runtime.recompose(function)

    def _reinstall(self) -> None:
        """Point every function on the per-receiver path at the current tables."""
        for function in self._functions:
            self.runtime.recompose(function)

    def _unmark(self) -> None:
        functions, self._functions = self._functions, set()
        for function in functions:
            function.receiver_kind = ""
            self.runtime.recompose(function)


def _nothing() -> None:
    return None


def _describe(receiver: object) -> str:
    if receiver is None:
        return "a collected object"
    if isinstance(receiver, type):
        return f"class {receiver.__qualname__}"
    try:
        shown = repr(receiver)
    except Exception:  # a receiver's own __repr__ may fail: name it by type and id
        shown = f"<{type(receiver).__qualname__} object at {id(receiver):#x}>"
    return f"object {shown}"


def _describe_level(level: object, receiver: object) -> str:
    if level is _OWN:
        return f"the own layers of {_describe(receiver)}"
    return f"the class-wide layers of {_describe(level)}"


def _subclasses(cls: type) -> list[type]:
    found: list[type] = []
    pending: list[type] = list(type.__subclasses__(cls)) if isinstance(cls, type) else []
    while pending:
        sub = pending.pop()
        if sub not in found:
            found.append(sub)
            pending.extend(type.__subclasses__(sub))
    return found


class Runtime:
    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.active: Configuration = ()
        self.epoch = 0
        self._functions: weakref.WeakSet[LayeredFunction] = weakref.WeakSet()
        self._observers: list[Callable[[SwitchEvent], object]] = []
        self._critical_depth = 0
        self._deferred: deque[tuple[Plan, SwitchResult]] = deque()
        self._live_scopes = 0
        self._scopes: weakref.WeakSet[_Scope] = weakref.WeakSet()
        self.scope: ContextVar[_Scope | None] = ContextVar("contextros_scope", default=None)
        # The scope entered last (weakly): the C dispatchers expect its heads.
        self._newest_scope: Callable[[], _Scope | None] = _nothing
        self.receivers = Receivers(self)

    # -- layered functions ---------------------------------------------------------------

    def adopt(self, function: LayeredFunction) -> None:
        with self.lock:
            self._functions.add(function)
            self.recompose(function)

    def recompose(self, function: LayeredFunction) -> None:
        with self.lock:
            function.global_head = function.head_for(self.active)
            self._install(function)

    def _install(self, function: LayeredFunction) -> None:
        """The path calls of `function` take: per receiver (a class or an object of its
        class has layers of its own), scope-reading (a `with` block is alive somewhere),
        or direct (the head's own code, or a one-call trampoline)."""
        if function.receiver_kind:
            function.install_receiver(self)
        elif self._live_scopes:
            function.install_scoped(self)
        else:
            function.install(function.global_head)

    def rewire(self, function: LayeredFunction) -> None:
        """`function`'s partials changed: recompose it, and give every live scope and
        every receiver (object or class with layers of its own) fresh heads (theirs were
        composed from the old partials), reinstalling the per-receiver functions."""
        with self.lock:
            self.recompose(function)
            for scope in list(self._scopes):
                scope.refresh(self.active)
            self.receivers.refresh(self.active)
            self.receivers._reinstall()

    def remove_layer(self, layer: Layer) -> tuple[str, ...]:
        """Deactivate `layer` (if decisively active), drop its partials from every layered
        function and forget its definition. Returns the qualnames of the functions it
        refined. A RelationError from the deactivation leaves everything as it was."""
        with self.lock:
            if layer in self.active:
                if self._critical_depth:
                    raise LayerDefinitionError(
                        f"cannot remove layer {layer.name} while it is active and a critical "
                        "section is open (its deactivation would be deferred)"
                    )
                remaining = tuple(other for other in self.active if other != layer)
                rules.validate(remaining)
                self._apply(remaining)
            refined = []
            for function in list(self._functions):
                if layer.name in function.partials:
                    function.remove_partial(layer.name)
                    refined.append(function.qualname)
            DEFINITIONS.unregister(layer.name)
            return tuple(sorted(refined))

    def _reinstall_all(self) -> None:
        for function in list(self._functions):
            self.recompose(function)

    # -- decisive switches ---------------------------------------------------------------

    def request(self, plan: Plan) -> SwitchResult:
        """Apply `plan` now, or queue it while a critical section is open."""
        with self.lock:
            if self._critical_depth:
                result = SwitchResult(deferred=True)
                self._deferred.append((plan, result))
                return result
            result = SwitchResult()
            try:
                epoch = self._apply(plan(self.active))
            except LayerError as error:
                result._settle(None, error)
                raise
            result._settle(epoch, None)
            return result

    def _apply(self, new: Configuration) -> int:
        old = self.active
        if new == old:
            return self.epoch
        leaving = [layer for layer in reversed(old) if layer not in new]
        arriving = [layer for layer in new if layer not in old]
        for layer in leaving:
            _run_hook(layer, "on_deactivate")  # raising here abandons the switch
        heads = {function: function.head_for(new) for function in list(self._functions)}
        self.active = new
        self.epoch += 1
        self.receivers.refresh(new)  # new receiver tables, installed just below
        for scope in list(self._scopes):
            scope.refresh(new)  # before: a dispatcher installed below reads the newest's heads
        for function, head in heads.items():
            function.global_head = head
            self._install(function)
        failure: HookError | None = None
        for layer in arriving:
            try:
                _run_hook(layer, "on_activate")
            except HookError as error:
                failure = failure or error
        event = SwitchEvent(self.epoch, old, new)
        for observer in list(self._observers):
            try:
                observer(event)
            except Exception:
                log.exception("contextros: observer %r failed on epoch %d", observer, self.epoch)
        if failure is not None:
            raise failure
        return self.epoch

    # -- critical sections ---------------------------------------------------------------

    @contextmanager
    def critical(self) -> Iterator[None]:
        with self.lock:
            self._critical_depth += 1
        try:
            yield
        finally:
            with self.lock:
                self._critical_depth -= 1
                if not self._critical_depth:
                    self._drain()

    @property
    def in_critical_section(self) -> bool:
        return self._critical_depth > 0

    def _drain(self) -> None:
        while self._deferred and not self._critical_depth:
            plan, result = self._deferred.popleft()
            try:
                epoch = self._apply(plan(self.active))
            except LayerError as error:
                log.warning("contextros: deferred switch rejected: %s", error)
                result._settle(None, error)
            else:
                result._settle(epoch, None)

    # -- observers -----------------------------------------------------------------------

    def subscribe(self, observer: Callable[[SwitchEvent], object]) -> Callable[[], None]:
        with self.lock:
            self._observers.append(observer)

        def unsubscribe() -> None:
            with self.lock:
                if observer in self._observers:
                    self._observers.remove(observer)

        return unsubscribe

    # -- scoped activation ---------------------------------------------------------------

    def enter_scope(self, steps: tuple[tuple[bool, Layer], ...]) -> _Scope:
        with self.lock:
            parent = self.scope.get()
            steps = (parent.steps if parent else ()) + steps
            rules.validate(rules.replay(self.active, steps))
            self._live_scopes += 1  # _Scope.__del__ gives it back
            scope = _Scope(self, steps)
            self._scopes.add(scope)
            self._newest_scope = weakref.ref(scope)
            if self._live_scopes == 1:
                self._reinstall_all()
            return scope

    def _scope_released(self) -> None:
        # Runs from __del__, wherever the last reference went (a finished task, another
        # thread): it only counts. A function left on the scope-reading path goes back to
        # the direct one at its next call with no scope (see `back_to_direct`) or here, in
        # `leave_scope`, at the end of a block.
        with self.lock:
            self._live_scopes -= 1

    def leave_scope(self) -> None:
        with self.lock:
            if not self._live_scopes:
                self._reinstall_all()

    def back_to_direct(self, function: LayeredFunction) -> None:
        """Called by `function`'s scope-reading path when it ran with no scope alive."""
        with self.lock:
            if not self._live_scopes:
                self.recompose(function)

    def newest_scope(self) -> _Scope | None:
        """The scope entered last, if it is still alive."""
        return self._newest_scope()

    @property
    def live_scopes(self) -> int:
        return self._live_scopes

    def reset(self) -> None:
        """Back to no active layers, no observers and no pending switches (for tests).

        The epoch keeps counting up: epochs never repeat in a process.
        """
        with self.lock:
            for _, result in self._deferred:
                result._settle(None, None)
            self._deferred.clear()
            self._critical_depth = 0
            self._observers.clear()
            self.active = ()
            self.epoch += 1
            for scope in list(self._scopes):
                scope.refresh(())
            self.receivers.forget_all()
            self._reinstall_all()

    def effective(self, receiver: object = None) -> Configuration:
        """The configuration a call sees: decisive, then the receiver's class-wide and own
        layers (when given), then the caller's scope."""
        scope = self.scope.get()
        if receiver is not None:
            found = self.receivers.of(receiver)
            if found is not None:
                base = found.heads[_CONFIGURATION]
                return base if scope is None else rules.replay(base, scope.steps)
        return self.active if scope is None else scope.configuration()


def _run_hook(layer: Layer, kind: str) -> None:
    definition = DEFINITIONS.find(layer.name) or layer
    hook = getattr(definition, kind)
    if hook is None:
        return
    try:
        hook()
    except Exception as error:
        raise HookError(f"{kind} hook of layer {layer.name} failed: {error}", layer.name) from error


RUNTIME = Runtime()
