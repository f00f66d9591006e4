"""Isolation for the examples' tests: one ROS domain per pytest-xdist worker (120 + index).

The domain is handed to the launcher and to `rclpy.init` explicitly rather than through
the environment, so other test folders setting their own `ROS_DOMAIN_ID` do not matter.
"""

from __future__ import annotations

import os

import pytest

DOMAIN_ID = 120 + int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)


@pytest.fixture
def domain_id() -> int:
    pytest.importorskip("rclpy")
    pytest.importorskip("contextros_interfaces", reason="run `make ros` to build the interfaces")
    return DOMAIN_ID
