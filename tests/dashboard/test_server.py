"""The dashboard's server against its ROS thread: a model change reported while (or after)
the server stops is dropped, not an error in the reporting thread (no ROS here)."""

from __future__ import annotations

import asyncio
import threading

import pytest

pytest.importorskip("aiohttp")

from contextros.dashboard.model import DashboardModel
from contextros.dashboard.server import DashboardServer


def test_a_change_reported_after_the_server_stopped_is_dropped() -> None:
    server = DashboardServer(DashboardModel(["/"]))

    async def run() -> None:
        runner, _ = await server.start("127.0.0.1", 0)
        server.notify()  # while serving: a wake-up
        await server.stop(runner)

    asyncio.run(run())  # the loop is closed now
    server.notify()


def test_changes_reported_from_another_thread_while_the_server_stops_raise_nothing() -> None:
    server = DashboardServer(DashboardModel(["/"]))
    errors: list[BaseException] = []
    done = threading.Event()

    def report() -> None:
        while not done.is_set():
            try:
                server.notify()
            except BaseException as error:
                errors.append(error)
                return

    async def run() -> None:
        runner, _ = await server.start("127.0.0.1", 0)
        await asyncio.sleep(0.05)
        await server.stop(runner)

    reporter = threading.Thread(target=report)
    reporter.start()
    asyncio.run(run())  # reported to all along, through the loop's close
    threading.Event().wait(0.05)
    done.set()
    reporter.join()
    assert errors == []
