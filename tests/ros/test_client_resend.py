"""`LayerClient.request` against a manager that answers late (a stand-in in this process,
as in test_client_probe.py): a short timeout is waited for until the client gives up (not
cut short where no resend fits), and an answer to any attempt of the command counts.
(The C++ client's: tests/ros/test_cpp_client.py, with the same stand-in.)"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

import pytest

rclpy = pytest.importorskip("rclpy")

from contextros_interfaces.srv import Activate, QueryRegistry  # noqa: E402
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from contextros.ros.client import REPLY_MARGIN, RESEND_AFTER, LayerClient  # noqa: E402
from contextros.ros.topics import (  # noqa: E402
    ACTIVATE_QOS,
    ACTIVATE_SERVICE,
    QUERY_QOS,
    QUERY_SERVICE,
)

LATE = RESEND_AFTER + 0.5  # the stand-in's time to answer each command
# A timeout that leaves no time for a resend: the client gives up at SHORT + REPLY_MARGIN
# (3.5 s), a second attempt at RESEND_AFTER would have SHORT + REPLY_MARGIN - RESEND_AFTER -
# REPLY_MARGIN < 0 s. It used to give up at RESEND_AFTER, before the answer at LATE.
SHORT = 1.5


@contextlib.contextmanager
def late_manager() -> Iterator[list[float]]:
    """A stand-in manager answering each Activate LATE after it arrives (its message says
    which one: "answer 1", ...), each on a thread of its own, in a ROS context of its own;
    yields their arrival times."""
    context = Context()
    rclpy.init(context=context)
    server = Node("late_manager_stand_in", context=context)
    arrived: list[float] = []

    def activate(request: Activate.Request, response: Activate.Response) -> object:
        arrived.append(time.monotonic())
        number = len(arrived)
        time.sleep(LATE)
        response.success = True
        response.message = f"answer {number}"
        return response

    server.create_service(
        Activate,
        ACTIVATE_SERVICE,
        activate,
        qos_profile=ACTIVATE_QOS,
        callback_group=ReentrantCallbackGroup(),
    )
    server.create_service(
        QueryRegistry, QUERY_SERVICE, lambda request, response: response, qos_profile=QUERY_QOS
    )
    executor = MultiThreadedExecutor(num_threads=4, context=context)
    executor.add_node(server)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    try:
        yield arrived
    finally:
        executor.shutdown(timeout_sec=10.0)
        spinning.join(timeout=10.0)
        server.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def arrived() -> Iterator[list[float]]:
    """The late stand-in, and rclpy's default context for the client under test."""
    rclpy.init()
    try:
        with late_manager() as times:
            yield times
    finally:
        rclpy.try_shutdown()


def arrivals(arrived: list[float], count: int) -> int:
    """How many commands reached the stand-in, once `count` did (or 3 s passed)."""
    deadline = time.monotonic() + 3.0
    while len(arrived) < count and time.monotonic() < deadline:
        time.sleep(0.01)
    return len(arrived)


def _client() -> LayerClient:
    client = LayerClient(Node("late_caller"))
    client.wait_for_manager(timeout=10.0)
    return client


def test_a_short_timeout_is_waited_for_until_the_client_gives_up(
    arrived: list[float],
) -> None:
    """No resend fits in a SHORT timeout, so the command sent is waited for (the client
    gave up at RESEND_AFTER)."""
    client = _client()
    started = time.monotonic()
    result = client.request(["Night"], timeout=SHORT)
    assert result.message == "answer 1", result
    assert LATE <= time.monotonic() - started < SHORT + REPLY_MARGIN
    assert len(arrived) == 1, "not sent again"


def test_a_late_answer_to_the_first_attempt_counts(arrived: list[float]) -> None:
    """No timeout: sent again after RESEND_AFTER, and the first attempt's answer, coming
    after that, is taken (it was dropped, and the last one's waited for)."""
    client = _client()
    started = time.monotonic()
    result = client.request(["Night"])
    elapsed = time.monotonic() - started
    assert result.message == "answer 1", result
    assert LATE <= elapsed < RESEND_AFTER + LATE, elapsed
    assert arrivals(arrived, 2) == 2, "sent again once"
