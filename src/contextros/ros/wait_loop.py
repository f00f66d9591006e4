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
other than QoS event handlers (actions): it would not run them. `spin_nodes` spins context
nodes (any nodes) with it by default, and hands them to rclpy's executor once a node has
what it refuses: with one participant per node, 64 nodes in 8 processes used about half
the CPU per synchronous activation (docs/benchmarks.md, "The participants' CPU"). A
callback that reaches for `node.executor` finds none under it.

Why not `rclpy.experimental.EventsExecutor` (tried, ros-rclpy 9.1.2 wheels): its `spin`
refuses the manager's node at once ("Guard conditions not supported": the manager wakes on
a guard condition when a bindings worker is done); and even a plain node with only a
timer, a subscription and a service had none of its callbacks run under it here.
"""

from __future__ import annotations

import contextlib
import inspect
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from functools import partial
from itertools import chain, compress
from operator import attrgetter
from typing import Any

from rclpy.context import Context
from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.timer import TimerInfo
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
        # How to read each kind of entity of every node (in `_KINDS`' order), once per wake-up.
        self._lists = _entity_lists(self.nodes)
        self._entities: tuple[tuple[Any, ...], ...] = ()
        self._held = contextlib.ExitStack()
        self._wait_set: Any = None
        # What the wait set waits on: per kind, the handles (added in this order) and the
        # entity of each handle's pointer (what get_ready_entities names).
        self._handles: dict[str, list[Any]] = {}
        self._by_pointer: dict[str, dict[int, Any]] = {}
        self._waitables: list[Any] = []
        # QoS event handlers (most of a node's waitables: one or two per publisher and
        # subscription) and their event handles: added and checked in bulk, without
        # rclpy's per-waitable calls.
        self._event_handlers: list[Any] = []
        self._event_handles: list[Any] = []
        self._event_indices: list[int] = []
        self._timer_info_arguments: dict[Any, str] = {}
        # Per subscription, the others on its topic (see `_take_from_siblings`).
        self._siblings: dict[Any, tuple[Any, ...]] = {}
        # Ready entities run kind by kind, in this order (as rclpy's executor orders them).
        self._runners: tuple[tuple[str, Callable[[Any], None]], ...] = (
            ("timer", self._run_timer),
            ("subscription", self._run_subscription),
            ("guard_condition", self._run_guard),
            ("client", self._run_client),
            ("service", self._run_service),
        )

    def spin_once(self, timeout_sec: float | None = None) -> None:
        if not self.nodes:  # shut down, or nothing to spin: nothing to wait on, or hold
            time.sleep(timeout_sec or 0.0)
            return
        nodes = self.nodes
        entities = tuple([tuple(chain.from_iterable(map(get, nodes))) for get in self._lists])
        if entities != self._entities:
            self._build(entities)
        self._fill()
        wait_set = self._wait_set
        wait_set.wait(timeout_sec_to_nsec(timeout_sec))
        ready_waitables = [w for w in self._waitables if w.is_ready(wait_set)]
        if self._event_handlers:
            indices = self._event_indices
            flags = map(partial(wait_set.is_ready, "event"), indices)
            for handler, index in compress(zip(self._event_handlers, indices, strict=True), flags):
                handler._event_index = index
                if handler.is_ready(wait_set):  # marks its event to be taken
                    ready_waitables.append(handler)
        for kind, run in self._runners:
            by_pointer = self._by_pointer[kind]
            if not by_pointer:
                continue
            ready = [by_pointer.get(pointer) for pointer in wait_set.get_ready_entities(kind)]
            for entity in ready:
                if entity is not None:
                    self._run_entity(entity, run)
            if kind == "subscription" and self._siblings and ready:
                self._take_from_siblings(ready)
        for waitable in ready_waitables:
            try:
                data = waitable.take_data()
            except InvalidHandle:  # its entity was destroyed by a callback of this wake-up
                self._entities = ()
                continue
            _run_to_completion(waitable.execute(data))

    def _run_entity(self, entity: Any, run: Callable[[Any], None]) -> None:
        handle = entity.handle
        try:
            handle.__enter__()
        except InvalidHandle:
            # Destroyed (its own destroy(), or its node's destroy_* in a callback of this
            # wake-up) while still listed: let go of at the next wake-up.
            self._entities = ()
            return
        try:
            run(entity)
        finally:
            handle.__exit__(None, None, None)

    def _take_from_siblings(self, ready: list[Any]) -> None:
        """A message that came to one subscription of a topic came to every subscription
        of that topic in these nodes (each context node's participant subscribes to the
        manager's state) within microseconds: the copies that arrived while the ready ones
        ran are taken now (a take that finds none costs 1 µs), not one wake-up later (a
        wake-up of 8 context nodes costs about 70 µs)."""
        done = set(ready)
        for entity in ready:
            for sibling in self._siblings.get(entity, ()):
                if sibling not in done:
                    done.add(sibling)
                    self._run_entity(sibling, self._run_subscription)

    def _fill(self) -> None:
        """The wait set, cleared and given every entity again (rcl_wait empties it), one
        kind at a time in C (`map`): a Python loop over 180 entities cost 0.17 ms."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        handles = self._handles
        consume(map(wait_set.add_subscription, handles["subscription"]))
        consume(map(wait_set.add_client, handles["client"]))
        consume(map(wait_set.add_service, handles["service"]))
        consume(map(wait_set.add_timer, handles["timer"]))
        consume(map(wait_set.add_guard_condition, handles["guard_condition"]))
        for waitable in self._waitables:
            waitable.add_to_wait_set(wait_set)
        self._event_indices = list(map(wait_set.add_event, self._event_handles))

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
        self._handles, self._by_pointer, self._siblings = {}, {}, {}
        self._waitables, self._event_handlers, self._event_handles = [], [], []
        self._event_indices = []

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
        for kind, members in (
            ("timer", timers),
            ("subscription", subscriptions),
            ("guard_condition", guards),
            ("client", clients),
            ("service", services),
        ):
            self._handles[kind] = [entity.handle for entity in members]
            self._by_pointer[kind] = {entity.handle.pointer: entity for entity in members}
        by_topic: dict[str, list[Any]] = {}
        for subscription in subscriptions:
            by_topic.setdefault(subscription.topic_name, []).append(subscription)
        self._siblings = {
            subscription: tuple(other for other in same if other is not subscription)
            for same in by_topic.values()
            if len(same) > 1
            for subscription in same
        }
        self._timer_info_arguments = {
            timer: argument for timer in timers if (argument := _timer_info_argument(timer))
        }
        events = [(waitable, _event_handle(waitable)) for waitable in waitables]
        self._event_handlers = [handler for handler, event in events if event is not None]
        self._event_handles = [event for _, event in events if event is not None]
        self._waitables = [waitable for waitable, event in events if event is None]

    def _run_timer(self, timer: Any) -> None:
        if not timer.handle.is_timer_ready():
            return
        info_argument = self._timer_info_arguments.get(timer)
        try:
            if info_argument is None:
                timer.handle.call_timer()
            else:
                info = timer.handle.call_timer_with_info()
        except Exception:  # a timer cancelled meanwhile (rclpy's TimerCancelledError)
            return
        if not timer.callback:
            return
        if info_argument is None:
            timer.callback()
        else:  # a callback taking a TimerInfo, as rclpy's executor gives it
            timer_info = TimerInfo(
                expected_call_time=info["expected_call_time"],
                actual_call_time=info["actual_call_time"],
                clock_type=timer.clock.clock_type,
            )
            timer.callback(**{info_argument: timer_info})

    @staticmethod
    def _run_guard(guard: Any) -> None:
        if guard.callback:
            guard.callback()

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
# The lists behind those properties in rclpy's Node (each property is a generator over one):
# read straight, in C, a wake-up of 8 context nodes checks its 150 entities in 4 µs, not 20.
_NODE_LISTS = (
    "_subscriptions",
    "_timers",
    "_clients",
    "_services",
    "_guards",
    "_Node__waitables",
)


def _entity_lists(nodes: Sequence[Node]) -> list[Callable[[Node], Iterable[Any]]]:
    """Per kind, what gives a node's entities of that kind: rclpy's list where every node
    has it, else the public property (another rclpy, or a node overriding one)."""
    if all(
        isinstance(getattr(node, name, None), list)
        and getattr(type(node), kind, None) is getattr(Node, kind)
        for node in nodes
        for kind, name in zip(_KINDS, _NODE_LISTS, strict=True)
    ):
        return [attrgetter(name) for name in _NODE_LISTS]
    return [attrgetter(kind) for kind in _KINDS]


class UnsupportedEntityError(TypeError):
    """A node has what `WaitLoop` cannot run: spin it with rclpy's executor. `reason` says
    what (naming the node and the entity)."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"{reason}; spin this node with rclpy's executor (lean=False)")
        self.reason = reason


_KIND_NAMES = {
    "subscriptions": "subscription",
    "timers": "timer",
    "services": "service",
    "guards": "guard condition",
}


def _check_supported(nodes: Sequence[Node]) -> None:
    """Refuse, naming the node and the entity, what this loop would silently not run:
    coroutine callbacks (nothing awaits them here) and waitables other than QoS event
    handlers (an action server's or client's `execute` awaits its goals)."""
    for node in nodes:
        for kind in ("subscriptions", "timers", "services", "guards"):
            for entity in getattr(node, kind):
                if inspect.iscoroutinefunction(entity.callback):
                    name = getattr(entity, "topic_name", None) or getattr(entity, "srv_name", "")
                    what = f"{_KIND_NAMES[kind]} {name}".rstrip()
                    raise UnsupportedEntityError(
                        f"node {node.get_fully_qualified_name()}: the {what} has a coroutine "
                        "callback, which WaitLoop does not await"
                    )
        for waitable in node.waitables:
            if isinstance(waitable, EventHandler) and inspect.iscoroutinefunction(
                waitable.callback
            ):
                raise UnsupportedEntityError(
                    f"node {node.get_fully_qualified_name()}: a QoS event handler has a "
                    "coroutine callback, which WaitLoop does not await"
                )
            if not isinstance(waitable, EventHandler):
                raise UnsupportedEntityError(
                    f"node {node.get_fully_qualified_name()}: WaitLoop runs only QoS event "
                    f"handlers among waitables, not {type(waitable).__name__} (an action's)"
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


def consume(iterator: Iterable[Any]) -> None:
    """Run an iterator through, in C (the `map`s of `_fill`)."""
    deque(iterator, maxlen=0)


def _timer_info_argument(timer: Any) -> str | None:
    """The parameter of `timer`'s callback annotated `TimerInfo`, if any (rclpy's rule; the
    annotation may also be the name, as under `from __future__ import annotations`)."""
    if timer.callback is None:
        return None
    try:
        parameters = inspect.signature(timer.callback).parameters.values()
    except (TypeError, ValueError):
        return None
    names = (TimerInfo, "TimerInfo", "rclpy.timer.TimerInfo")
    return next((p.name for p in parameters if p.annotation in names), None)


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
