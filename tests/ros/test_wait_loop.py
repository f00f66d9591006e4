"""`WaitLoop`, the manager's lean replacement for rclpy's executor, serves every kind of
entity a node has: timers, subscriptions, services, clients and guard conditions (real
rclpy, one process, its own context)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402
from rclpy.exceptions import InvalidHandle  # noqa: E402
from rclpy.node import Node  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from contextros.ros.wait_loop import UnsupportedEntityError, WaitLoop  # noqa: E402


@pytest.fixture
def context() -> Iterator[Context]:
    context = Context()
    rclpy.init(context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


def test_every_kind_of_entity_is_served(context: Context) -> None:
    server = Node("wait_loop_server", context=context)
    caller = Node("wait_loop_caller", context=context)
    seen: dict[str, object] = {}

    def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = True, "served"
        return response

    server.create_service(Trigger, "wait_loop/trigger", serve)
    server.create_subscription(String, "wait_loop/topic", lambda m: seen.update(msg=m.data), 10)
    server.create_timer(0.01, lambda: seen.update(ticks=int(seen.get("ticks", 0)) + 1))  # type: ignore[call-overload]
    guard = server.create_guard_condition(lambda: seen.update(guard=True))
    publisher = caller.create_publisher(String, "wait_loop/topic", 10)
    client = caller.create_client(Trigger, "wait_loop/trigger")
    loop = WaitLoop([server, caller], context=context)
    deadline = time.monotonic() + 10.0
    future = None
    guard.trigger()
    while time.monotonic() < deadline:
        loop.spin_once(0.05)
        if future is None and client.service_is_ready():
            future = client.call_async(Trigger.Request())
        if publisher.get_subscription_count():
            publisher.publish(String(data="hello"))
        if future is not None and future.done() and "msg" in seen and seen.get("ticks", 0) >= 3:
            break
    assert future is not None and future.done(), "the service or the client was not served"
    assert future.result().message == "served"
    assert seen.get("msg") == "hello"
    assert int(seen.get("ticks", 0)) >= 3  # type: ignore[call-overload]
    assert seen.get("guard") is True
    loop.shutdown()
    server.destroy_node()
    caller.destroy_node()


def test_every_request_and_response_waiting_is_served_in_one_wake_up(context: Context) -> None:
    """A wake-up costs more than a request (issue 16's storm: 0.2 ms of CPU): the loop takes
    every request waiting at a service, and every response waiting at a client, at once."""
    server = Node("wait_loop_batch_server", context=context)
    caller = Node("wait_loop_batch_caller", context=context)
    served: list[int] = []

    def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        served.append(len(served))
        response.success = True
        return response

    server.create_service(Trigger, "wait_loop/batch", serve)
    client = caller.create_client(Trigger, "wait_loop/batch")
    serving, calling = WaitLoop([server], context=context), WaitLoop([caller], context=context)
    deadline = time.monotonic() + 10.0
    while not client.service_is_ready() and time.monotonic() < deadline:
        serving.spin_once(0.05)
        calling.spin_once(0.0)
    futures = [client.call_async(Trigger.Request()) for _ in range(5)]
    time.sleep(0.5)  # all five delivered, none taken
    serving.spin_once(1.0)
    assert len(served) == 5
    time.sleep(0.5)
    calling.spin_once(1.0)
    assert [future.done() for future in futures] == [True] * 5
    serving.shutdown()
    calling.shutdown()


def test_entities_created_or_destroyed_between_wake_ups_are_taken_in_or_let_go(
    context: Context,
) -> None:
    """The loop keeps its wait set while the entities stay the same: a new subscription is
    served from the next wake-up, and a destroyed one is released there (its handle is
    destroyed, not held) and never called again."""
    node = Node("wait_loop_changes", context=context)
    publisher = node.create_publisher(String, "wait_loop/changes", 10)
    loop = WaitLoop([node], context=context)
    loop.spin_once(0.0)  # built without the subscription
    seen: list[str] = []
    subscription = node.create_subscription(
        String, "wait_loop/changes", lambda m: seen.append(m.data), 10
    )
    deadline = time.monotonic() + 10.0
    while not seen and time.monotonic() < deadline:
        publisher.publish(String(data="first"))
        loop.spin_once(0.05)
    assert seen and seen[0] == "first", "a subscription created after the first wake-up"
    handle = subscription.handle
    node.destroy_subscription(subscription)
    publisher.publish(String(data="after"))
    loop.spin_once(0.2)
    assert "after" not in seen
    with pytest.raises(InvalidHandle), handle:  # released by the loop, so destroyed
        pass
    loop.shutdown()
    node.destroy_node()


def test_an_entity_destroyed_by_itself_is_let_go_and_the_loop_goes_on(context: Context) -> None:
    """`subscription.destroy()` (or leaving `with node.create_subscription(...)`) destroys an
    entity its node still lists: the loop builds its wait set again without it."""
    node = Node("wait_loop_self_destroyed", context=context)
    publisher = node.create_publisher(String, "wait_loop/self_destroyed", 10)
    seen: list[str] = []
    gone = node.create_subscription(String, "wait_loop/self_destroyed", seen.append, 10)
    kept: list[str] = []
    node.create_subscription(String, "wait_loop/self_destroyed", kept.append, 10)
    loop = WaitLoop([node], context=context)
    loop.spin_once(0.0)
    gone.destroy()
    deadline = time.monotonic() + 10.0
    while not kept and time.monotonic() < deadline:
        publisher.publish(String(data="after"))
        loop.spin_once(0.05)
    assert kept and not seen
    loop.shutdown()
    loop.spin_once(0.0)  # after shutdown: nothing held, nothing done
    node.destroy_node()


def test_what_the_loop_would_not_run_is_refused_by_name(context: Context) -> None:
    """A coroutine callback (nothing would await it) or a waitable other than a QoS event
    handler (an action's `execute` awaits its goals; no action type is installed here, so
    a waitable of the test's own stands for one): refused with the node and the entity,
    before any wake-up runs anything."""
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
    from rclpy.waitable import Waitable

    class GoalWaitable(Waitable[None]):
        pass

    async def on_message(message: String) -> None:
        del message

    node = Node("wait_loop_async", context=context)
    node.create_subscription(String, "wait_loop/async", on_message, 10)
    with pytest.raises(UnsupportedEntityError, match=r"/wait_loop_async: the subscription "):
        WaitLoop([node], context=context).spin_once(0.0)
    node.destroy_node()
    node = Node("wait_loop_action", context=context)
    node.add_waitable(GoalWaitable(MutuallyExclusiveCallbackGroup()))
    with pytest.raises(UnsupportedEntityError, match=r"/wait_loop_action: .* not GoalWaitable"):
        WaitLoop([node], context=context).spin_once(0.0)
    node.destroy_node()
    # A context node (subscriptions, timers, services, QoS event handlers) is served.
    plain = Node("wait_loop_plain", context=context)
    plain.create_subscription(String, "wait_loop/plain", lambda m: None, 10)
    loop = WaitLoop([plain], context=context)
    loop.spin_once(0.0)
    loop.shutdown()
    plain.destroy_node()


def test_a_qos_event_is_taken_and_its_callback_run(context: Context) -> None:
    """QoS event handlers are served on the loop's fast path: an incompatible QoS event
    (a reliable reader, a best-effort writer) reaches its callback, and is taken (else the
    wait set would wake at once, again and again)."""
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    node = Node("wait_loop_events", context=context)
    seen: list[object] = []
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    callbacks = SubscriptionEventCallbacks(incompatible_qos=seen.append)
    node.create_subscription(
        String, "wait_loop/events", lambda m: None, reliable, event_callbacks=callbacks
    )
    node.create_publisher(String, "wait_loop/events", best_effort)
    loop = WaitLoop([node], context=context)
    deadline = time.monotonic() + 10.0
    while not seen and time.monotonic() < deadline:
        loop.spin_once(0.05)
    assert len(seen) == 1 and seen[0].total_count == 1  # type: ignore[attr-defined]
    # Taken: nothing is ready any more, so a wake-up waits its whole timeout.
    started = time.monotonic()
    loop.spin_once(0.2)
    assert time.monotonic() - started >= 0.15
    loop.shutdown()
    node.destroy_node()


def test_timer_info_coroutine_guards_and_an_event_of_a_destroyed_entity(
    context: Context,
) -> None:
    """What rclpy's executor does, the loop does too: a timer callback taking a `TimerInfo`
    gets one; a coroutine guard-condition callback is refused by name; a QoS event whose
    subscription a callback destroyed in the same wake-up is let go, not raised."""
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.timer import TimerInfo

    node = Node("wait_loop_timer_info", context=context)
    infos: list[TimerInfo] = []

    def on_tick(info: TimerInfo) -> None:
        infos.append(info)

    node.create_timer(0.001, on_tick)  # type: ignore[arg-type]
    loop = WaitLoop([node], context=context)
    deadline = time.monotonic() + 5.0
    while not infos and time.monotonic() < deadline:
        loop.spin_once(0.05)
    assert infos and infos[0].actual_call_time.nanoseconds > 0
    loop.shutdown()
    node.destroy_node()

    async def on_guard() -> None:
        pass

    node = Node("wait_loop_async_guard", context=context)
    node.create_guard_condition(on_guard)  # type: ignore[arg-type]
    with pytest.raises(UnsupportedEntityError, match=r"the guard condition has a coroutine"):
        WaitLoop([node], context=context).spin_once(0.0)
    node.destroy_node()

    node = Node("wait_loop_event_destroyed", context=context)
    events: list[object] = []
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    subscription = node.create_subscription(
        String,
        "wait_loop/event_destroyed",
        lambda m: None,
        reliable,
        event_callbacks=SubscriptionEventCallbacks(incompatible_qos=events.append),
    )
    node.create_publisher(String, "wait_loop/event_destroyed", best_effort)
    # Ready in the same wake-up as the event (nothing spun meanwhile): a timer that destroys
    # the subscription, run first (timers before waitables).
    node.create_timer(0.001, lambda: node.destroy_subscription(subscription))
    time.sleep(0.5)
    loop = WaitLoop([node], context=context)
    loop.spin_once(0.0)
    for _ in range(5):
        loop.spin_once(0.01)  # goes on without the destroyed subscription and its events
    assert not list(node.subscriptions) and not events
    loop.shutdown()
    node.destroy_node()


def test_subscriptions_of_one_topic_each_get_every_message_once_in_order(
    context: Context,
) -> None:
    """A wake-up that runs one subscription of a topic also takes what its siblings (the
    other subscriptions of that topic in these nodes) got meanwhile: each message still
    reaches each of them exactly once, in order."""
    node = Node("wait_loop_siblings", context=context)
    got: dict[int, list[str]] = {0: [], 1: [], 2: []}
    for index in got:
        node.create_subscription(String, "wait_loop/siblings", got[index].append, 100)
    publisher = node.create_publisher(String, "wait_loop/siblings", 100)
    loop = WaitLoop([node], context=context)
    deadline = time.monotonic() + 10.0
    while publisher.get_subscription_count() < 3 and time.monotonic() < deadline:
        loop.spin_once(0.01)
    sent = [String(data=str(n)) for n in range(50)]
    for message in sent:
        publisher.publish(message)
    while any(len(messages) < len(sent) for messages in got.values()):
        assert time.monotonic() < deadline, {index: len(m) for index, m in got.items()}
        loop.spin_once(0.01)
    for _ in range(5):
        loop.spin_once(0.01)
    assert all(messages == sent for messages in got.values())
    loop.shutdown()
    node.destroy_node()
