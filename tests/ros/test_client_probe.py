"""`LayerClient.wait_for_manager` on a loaded machine: a manager whose answers take longer
than the client's first wait is still found (an earlier probe's answer counts)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

rclpy = pytest.importorskip("rclpy")

from contextros_interfaces.srv import Activate, QueryRegistry  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from contextros.ros.client import PROBE, LayerClient  # noqa: E402
from contextros.ros.topics import (  # noqa: E402
    ACTIVATE_QOS,
    ACTIVATE_SERVICE,
    QUERY_QOS,
    QUERY_SERVICE,
)

SLOW = 3 * PROBE  # the stand-in manager's time to answer a query


@pytest.fixture
def context() -> Iterator[Context]:
    """The default context (the client spins its node with rclpy's global executor)."""
    rclpy.init()
    try:
        yield rclpy.get_default_context()
    finally:
        rclpy.try_shutdown()


def test_a_manager_slower_than_a_probe_is_still_found(context: Context) -> None:
    server = Node("slow_manager_stand_in", context=context)
    asked: list[float] = []

    def query(request: QueryRegistry.Request, response: QueryRegistry.Response) -> object:
        asked.append(time.monotonic())
        time.sleep(SLOW)
        return response

    server.create_service(
        Activate, ACTIVATE_SERVICE, lambda request, response: response, qos_profile=ACTIVATE_QOS
    )
    server.create_service(QueryRegistry, QUERY_SERVICE, query, qos_profile=QUERY_QOS)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(server)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    caller = Node("probe_caller")
    client = LayerClient(caller)
    try:
        started = time.monotonic()
        client.wait_for_manager(timeout=10.0 * SLOW)
        assert asked, "the stand-in was asked"
        assert time.monotonic() - started < 10.0 * SLOW
    finally:
        executor.shutdown(timeout_sec=5.0)
        spinning.join(timeout=5.0)  # the stand-in's last slow answer sent before it goes
        caller.destroy_node()
        server.destroy_node()
