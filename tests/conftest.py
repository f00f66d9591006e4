"""Shared test set-up: every test starts from an empty decisive configuration."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from contextros.core.runtime import RUNTIME
from tests.ros.processes import ProcessGroup

# The commands a test runs ask the manager themselves: a daemon started by one would outlive
# the test (tests/ros/test_cli_daemon.py runs the daemon, in a directory of its own).
os.environ["CONTEXTROS_NO_DAEMON"] = "1"


@pytest.fixture(autouse=True)
def fresh_runtime() -> Iterator[None]:
    RUNTIME.reset()
    yield
    RUNTIME.reset()


@pytest.fixture
def processes() -> Iterator[ProcessGroup]:
    """Child processes started by one test, all killed when it ends (tests/ros, tests/install)."""
    group = ProcessGroup()
    try:
        yield group
    finally:
        group.kill_all()
