"""A lean replacement for rclpy's SingleThreadedExecutor, for a process that must answer
many messages (the Layer manager).

Profiled with 16 participants during back-to-back synchronous activations, the manager
spent about half its time in rclpy's executor rather than in its callbacks: every wake-up
filters every entity through its callback group, wraps each ready one in a `Task` and a
coroutine, and walks the nodes again to find what is ready. This loop waits on the same
entities and calls the callbacks directly: one wait set per wake-up, a lookup per ready
entity, no tasks, and every request or response already waiting taken in one go (during a
storm of 1,800 commands: 386 wake-ups instead of 1,934). It serves what the
manager's node has (subscriptions, services, timers, clients, guard conditions and
waitables such as QoS event handlers), single-threaded, in a fixed order per wake-up
(timers, subscriptions, guard conditions, clients, services, waitables). It refuses
(UnsupportedEntityError, naming the node and the entity) coroutine callbacks and waitables
other than QoS event handlers (actions): it would not run them. Context nodes whose
callbacks are plain functions can spin with it too (`spin_nodes(nodes, lean=True)`):
with one participant per node, 64 nodes in 8 processes acknowledged a synchronous
activation in 23 ms instead of 41 ms (docs/benchmarks.md). A callback that reaches for
`node.executor` finds none under it.

Why not `rclpy.experimental.EventsExecutor` (tried, ros-rclpy 9.1.2 wheels): its `spin`
refuses the manager's node at once ("Guard conditions not supported": the manager wakes on
a guard condition when a bindings worker is done); and even a plain node with only a
timer, a subscription and a service had none of its callbacks run under it here.
"""

from __future__ import annotations

import contextlib
import inspect
import time
from collections.abc import Sequence
from typing import Any

from rclpy.context import Context
from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.utilities import get_default_context, timeout_sec_to_nsec

# Requests (responses) taken from one service (client) per wake-up at most.
SERVICE_BATCH = 64


class WaitLoop:
    """Spins `nodes`: `spin_once(timeout_sec)` runs what is ready, waiting at most that long.

    The wait set, and the use of every entity's handle, are kept from one wake-up to the
    next while the nodes' entities stay the same (most of a wake-up's Python work was
    building them): an entity destroyed meanwhile is released at the next wake-up, when
    it is gone from its node, and `shutdown` releases them all."""

    def __init__(self, nodes: Sequence[Node], context: Context | None = None) -> None:
        self.nodes = list(nodes)
        self.context = context or get_default_context()
        self._entities: tuple[tuple[Any, ...], ...] = ()
        self._held = contextlib.ExitStack()
        self._wait_set: Any = None
        # What the wait set waits on, by kind, with the handles still usable.
        self._timers: list[Any] = []
        self._subscriptions: list[Any] = []
        self._guards: list[Any] = []
        self._clients: list[Any] = []
        self._services: list[Any] = []
        self._waitables: list[Any] = []
        # QoS event handlers (most of a node's waitables: one or two per publisher and
        # subscription), with their event handles: added and checked without rclpy's
        # per-waitable calls.
        self._events: list[tuple[Any, Any]] = []

    def spin_once(self, timeout_sec: float | None = None) -> None:
        if not self.nodes:  # shut down, or nothing to spin: nothing to wait on, or hold
            time.sleep(timeout_sec or 0.0)
            return
        entities = tuple(
            tuple(entity for node in self.nodes for entity in getattr(node, kind))
            for kind in _KINDS
        )
        if entities != self._entities:
            self._build(entities)
        try:
            self._fill()
        except InvalidHandle:
            # An entity destroyed with its own destroy(), still listed by its node (rclpy
            # lists it until the node destroys it): taken out by building again.
            self._build(entities)
            self._fill()
        wait_set = self._wait_set
        wait_set.wait(timeout_sec_to_nsec(timeout_sec))
        ready_waitables = [w for w in self._waitables if w.is_ready(wait_set)]
        if self._events:
            is_ready = wait_set.is_ready
            ready_waitables += [  # (the handler's own is_ready marks its event to take)
                handler
                for handler, _ in self._events
                if is_ready("event", handler._event_index) and handler.is_ready(wait_set)
            ]
        if self._timers:
            ready = set(wait_set.get_ready_entities("timer"))
            for timer in self._timers:
                if timer.handle.pointer in ready and timer.handle.is_timer_ready():
                    self._run_timer(timer)
        if self._subscriptions:
            ready = set(wait_set.get_ready_entities("subscription"))
            for subscription in self._subscriptions:
                if subscription.handle.pointer in ready:
                    self._run_subscription(subscription)
        if self._guards:
            ready = set(wait_set.get_ready_entities("guard_condition"))
            for guard in self._guards:
                if guard.handle.pointer in ready and guard.callback:
                    guard.callback()
        if self._clients:
            ready = set(wait_set.get_ready_entities("client"))
            for client in self._clients:
                if client.handle.pointer in ready:
                    self._run_client(client)
        if self._services:
            ready = set(wait_set.get_ready_entities("service"))
            for service in self._services:
                if service.handle.pointer in ready:
                    self._run_service(service)
        for waitable in ready_waitables:
            _run_to_completion(waitable.execute(waitable.take_data()))

    def _fill(self) -> None:
        """The wait set, cleared and given every entity again (rcl_wait empties it)."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for subscription in self._subscriptions:
            wait_set.add_subscription(subscription.handle)
        for client in self._clients:
            wait_set.add_client(client.handle)
        for service in self._services:
            wait_set.add_service(service.handle)
        for timer in self._timers:
            wait_set.add_timer(timer.handle)
        for guard in self._guards:
            wait_set.add_guard_condition(guard.handle)
        for waitable in self._waitables:
            waitable.add_to_wait_set(wait_set)
        add_event = wait_set.add_event
        for handler, event in self._events:
            # Entering raises InvalidHandle once its subscription or publisher was
            # destroyed by itself (still listed by the node): the loop then builds again.
            with event:
                handler._event_index = add_event(event)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        del timeout_sec
        self.nodes = []
        self._release()
        return True

    def _release(self) -> None:
        """Let go of every handle (what was destroyed meanwhile is destroyed now)."""
        self._wait_set = None
        self._held.close()
        self._entities = ()
        self._timers, self._subscriptions, self._guards = [], [], []
        self._clients, self._services, self._waitables = [], [], []
        self._events = []

    def _build(self, entities: tuple[tuple[Any, ...], ...]) -> None:
        _check_supported(self.nodes)
        self._release()
        held = contextlib.ExitStack()
        try:
            subscriptions, timers, clients, services, guards = (
                _usable(held, [entity.handle for entity in kind], kind) for kind in entities[:5]
            )
            waitables = _usable(held, entities[5], entities[5])  # each holds its handles
            counts = [0, 0, 0, 0, 0, 0]  # subscriptions, guards, timers, clients, services, events
            for waitable in waitables:
                extra = waitable.get_num_entities()
                counts[0] += extra.num_subscriptions
                counts[1] += extra.num_guard_conditions
                counts[2] += extra.num_timers
                counts[3] += extra.num_clients
                counts[4] += extra.num_services
                counts[5] += extra.num_events
            context = self.context.handle
            if context is None:
                raise RuntimeError("the ROS context is shut down")
            held.enter_context(context)
            self._wait_set = _rclpy.WaitSet(
                counts[0] + len(subscriptions),
                counts[1] + len(guards),
                counts[2] + len(timers),
                counts[3] + len(clients),
                counts[4] + len(services),
                counts[5],
                context,
            )
        except BaseException:
            held.close()
            raise
        self._held = held
        self._entities = entities
        self._timers, self._subscriptions, self._guards = timers, subscriptions, guards
        self._waitables = [w for w in waitables if _event_handle(w) is None]
        self._events = [(w, event) for w in waitables if (event := _event_handle(w)) is not None]
        self._clients, self._services = clients, services

    @staticmethod
    def _run_timer(timer: Any) -> None:
        try:
            timer.handle.call_timer()
        except Exception:  # a timer cancelled meanwhile (rclpy's TimerCancelledError)
            return
        if timer.callback:
            timer.callback()

    @staticmethod
    def _run_subscription(subscription: Any) -> None:
        taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
        if taken is None:
            return
        if subscription._callback_type is Subscription.CallbackType.MessageOnly:
            subscription.callback(taken[0])
        else:
            subscription.callback(*taken)

    @staticmethod
    def _run_client(client: Any) -> None:
        for _ in range(SERVICE_BATCH):  # every response waiting, as for services
            header, response = client.handle.take_response(client.srv_type.Response)
            if header is None:
                return
            try:
                future = client.get_pending_request(header.request_id.sequence_number)
            except KeyError:
                continue  # the request was cancelled
            future.set_result(response)

    @staticmethod
    def _run_service(service: Any) -> None:
        # Every request already waiting, not one per wake-up: a wake-up (the wait set
        # rebuilt and waited on) costs more CPU than a request here (0.2 ms, measured).
        for _ in range(SERVICE_BATCH):
            request, header = service.handle.service_take_request(service.srv_type.Request)
            if header is None:
                return
            response = service.callback(request, service.srv_type.Response())
            service.send_response(response, header)


# Node attributes listing each kind of entity, in the order `_build` takes them.
_KINDS = ("subscriptions", "timers", "clients", "services", "guards", "waitables")


class UnsupportedEntityError(TypeError):
    """A node has what `WaitLoop` cannot run: spin it with rclpy's executor."""


def _check_supported(nodes: Sequence[Node]) -> None:
    """Refuse, naming the node and the entity, what this loop would silently not run:
    coroutine callbacks (nothing awaits them here) and waitables other than QoS event
    handlers (an action server's or client's `execute` awaits its goals)."""
    for node in nodes:
        for kind in ("subscriptions", "timers", "services"):
            for entity in getattr(node, kind):
                if inspect.iscoroutinefunction(entity.callback):
                    what = getattr(entity, "topic_name", None) or getattr(entity, "srv_name", "")
                    raise UnsupportedEntityError(
                        f"node {node.get_fully_qualified_name()}: the {kind[:-1]} "
                        f"{what or '(timer)'} has a coroutine callback, which WaitLoop does "
                        "not await; spin this node with rclpy's executor (spin_nodes(..., "
                        "lean=False))"
                    )
        for waitable in node.waitables:
            if not isinstance(waitable, EventHandler):
                raise UnsupportedEntityError(
                    f"node {node.get_fully_qualified_name()}: WaitLoop runs only QoS event "
                    f"handlers among waitables, not {type(waitable).__name__} (actions need "
                    "rclpy's executor: spin_nodes(..., lean=False))"
                )


def _usable(
    held: contextlib.ExitStack, handles: Sequence[Any], entities: Sequence[Any]
) -> list[Any]:
    """The entities whose handles are still valid, each handle held in use by `held`."""
    usable = []
    for handle, entity in zip(handles, entities, strict=True):
        try:
            held.enter_context(handle)
        except InvalidHandle:
            continue  # destroyed meanwhile
        usable.append(entity)
    return usable


def _event_handle(waitable: Any) -> Any:
    """A QoS event handler's event handle (rclpy keeps it private), or None."""
    if type(waitable) is not EventHandler:
        return None
    return getattr(waitable, "_EventHandler__event", None)


def _run_to_completion(coroutine: Any) -> None:
    """A waitable's `execute` is a coroutine that awaits nothing here: run it through."""
    with contextlib.suppress(StopIteration):
        coroutine.send(None)
        coroutine.close()
