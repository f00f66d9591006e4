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
from contextros.core.configuration import Configuration
from contextros.core.layer import Layer
from contextros.core.layered import LayeredFunction
from contextros.errors import HookError, LayerError

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


class _Scope:
    """The scoped (de)activations of one `with activated/deactivated` block and its parents.

    Alive while any context (thread, task, copied context) can still see it; the
    runtime uses the live count to know whether calls must consult context variables.
    It caches its configuration and the heads composed for it until the next decisive
    switch.
    """

    __slots__ = ("__weakref__", "_configuration", "_epoch", "_runtime", "heads", "steps")

    def __init__(self, runtime: Runtime, steps: tuple[tuple[bool, Layer], ...]) -> None:
        self._runtime = runtime
        self.steps = steps
        self._epoch = -1
        self._configuration: Configuration = ()
        # Valid for `_epoch` only: a decisive switch replaces it (see configuration()).
        self.heads: dict[LayeredFunction, Callable[..., Any]] = {}

    def configuration(self) -> Configuration:
        if self._epoch != self._runtime.epoch:
            self._epoch = self._runtime.epoch
            self._configuration = rules.replay(self._runtime.active, self.steps)
            self.heads = {}
        return self._configuration

    def invalidate(self) -> None:
        self._epoch = -1
        self.heads = {}

    def head(self, function: LayeredFunction) -> Callable[..., Any]:
        if self._epoch != self._runtime.epoch:
            self.configuration()
        head = self.heads.get(function)
        if head is None:
            head = self.heads[function] = function.head_for(self._configuration)
        return head

    def __del__(self) -> None:
        self._runtime._scope_released()


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

    # -- layered functions ---------------------------------------------------------------

    def adopt(self, function: LayeredFunction) -> None:
        with self.lock:
            self._functions.add(function)
            self.recompose(function)

    def recompose(self, function: LayeredFunction) -> None:
        with self.lock:
            function.global_head = function.head_for(self.active)
            if self._live_scopes:
                function.install_scoped(self.scope)
            else:
                function.install(function.global_head)

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
        for function, head in heads.items():
            function.global_head = head
            if self._live_scopes:
                function.install_scoped(self.scope)
            else:
                function.install(head)
        for scope in list(self._scopes):
            scope.invalidate()
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
            if self._live_scopes == 1:
                self._reinstall_all()
            return scope

    def _scope_released(self) -> None:
        with self.lock:
            self._live_scopes -= 1

    def leave_scope(self) -> None:
        with self.lock:
            if not self._live_scopes:
                self._reinstall_all()

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
                scope.invalidate()
            self._reinstall_all()

    def effective(self) -> Configuration:
        scope = self.scope.get()
        return self.active if scope is None else scope.configuration()


def _run_hook(layer: Layer, kind: str) -> None:
    from contextros.core import registry

    definition = registry.find(layer.name) or layer
    hook = getattr(definition, kind)
    if hook is None:
        return
    try:
        hook()
    except Exception as error:
        raise HookError(f"{kind} hook of layer {layer.name} failed: {error}", layer.name) from error


RUNTIME = Runtime()
