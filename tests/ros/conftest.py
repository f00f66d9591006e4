"""Isolation for tests that start real ROS 2 processes.

Every pytest-xdist worker gets its own ROS_DOMAIN_ID (60 + worker index, or the next one
no other test process on this machine holds: two test runs at once must not hear each
other's managers), discovery stays on this machine, and RMW_IMPLEMENTATION is cleared (the
pip wheels only have Fast DDS and rcl kills a process asking for another). Set here, at
import, so that the test process's own rclpy and every child process inherit it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import TYPE_CHECKING

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("contextros_interfaces", reason="run `make ros` to build the interfaces")

from tests.ros.processes import reserve_domain_id

if TYPE_CHECKING:
    from contextros.ros import LayerClient

_worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
DOMAIN_ID = reserve_domain_id(60 + _worker)
os.environ["ROS_DOMAIN_ID"] = str(DOMAIN_ID)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("RMW_IMPLEMENTATION", None)
os.environ.pop("ROS_STATIC_PEERS", None)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if "tests/ros/" in str(item.path).replace(os.sep, "/"):
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope="module")
def client() -> Iterator[LayerClient]:
    """An activation client in the test process itself (rclpy initialised per module)."""
    import rclpy
    from rclpy.node import Node

    from contextros.ros import LayerClient

    rclpy.init()
    node = Node("contextros_test_client")
    try:
        yield LayerClient(node, requester="pytest")
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
