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


def _client() -> LayerClient:
    client = LayerClient(Node("late_caller"))
    client.wait_for_manager(timeout=10.0)
    return client


def test_a_short_timeout_is_waited_for_until_the_client_gives_up(
    arrived: list[float],
) -> None:
    """timeout=1: no resend fits (its own would end after the client gave up at 3 s), so
    the command sent is waited for; it was cut short at 2 s."""
    client = _client()
    started = time.monotonic()
    result = client.request(["Night"], timeout=1.0)
    assert result.message == "answer 1", result
    assert LATE <= time.monotonic() - started < 1.0 + REPLY_MARGIN
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
    assert len(arrived) == 2, "sent again once"
