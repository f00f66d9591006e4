"""Isolation for the examples' tests: a ROS domain of their own per pytest-xdist worker.

Domains start at 120 (tests/ros uses 60 and up). Several test runs can share one machine
(people, CI jobs), so each run also takes an offset derived from its xdist run id (or its
pid without xdist): two runs at once collide with a chance of 1 in 25, not always. The
domain is handed to the launcher and to `rclpy.init` explicitly rather than through the
environment, so other test folders setting their own `ROS_DOMAIN_ID` do not matter.
"""

from __future__ import annotations

import os
import zlib

import pytest

_RUN = os.environ.get("PYTEST_XDIST_TESTRUNUID") or str(os.getpid())
_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
DOMAIN_ID = 120 + (zlib.crc32(_RUN.encode()) % 25) * 4 + _WORKER % 4  # 120..219


@pytest.fixture
def domain_id() -> int:
    pytest.importorskip("rclpy")
    pytest.importorskip("contextros_interfaces", reason="run `make ros` to build the interfaces")
    return DOMAIN_ID
