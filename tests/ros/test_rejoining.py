"""A node that rejoins during a synchronous command counts for it (issue 24, item 3)."""

from __future__ import annotations

import signal
import threading

import rclpy

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import settle, start_system, wait_registry


def test_expect_count_counts_a_node_that_rejoins(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["e1"])
    settle(client, "Indoor")
    e1 = system.participants["e1"]
    e1.signal(signal.SIGSTOP)
    try:
        wait_registry(client, lambda r: "/e1" in r.dropped, what="/e1 dropped")
        # An active layer can be deactivated with no participant live.
        future = client.request_async([], ["Indoor"], synchronous=True, timeout=4, expect_count=1)
        threading.Timer(0.5, e1.signal, args=(signal.SIGCONT,)).start()
        rclpy.spin_until_future_complete(client.node, future, timeout_sec=7)
    finally:
        e1.signal(signal.SIGCONT)
    result = client.result_of(future)
    # Before: "applied by 0 node(s), 1 expected" at the timeout, /e1 on that epoch.
    assert result.success, result.message
    assert result.acknowledged == ("/e1",)
    assert result.elapsed < 3, result.elapsed


def test_a_node_that_rejoins_during_a_synchronous_command_is_counted(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["j1", "j2"])
    settle(client, "Indoor")
    j1, j2 = system.participants["j1"], system.participants["j2"]
    j2.signal(signal.SIGSTOP)
    try:
        wait_registry(client, lambda r: "/j2" in r.dropped, what="/j2 dropped")
        j1.send("critical 1.5")  # the command stays pending while /j2 comes back
        j1.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5)
        future = client.request_async(["Night"], synchronous=True, timeout=5)
        threading.Timer(0.3, j2.signal, args=(signal.SIGCONT,)).start()
        rclpy.spin_until_future_complete(client.node, future, timeout_sec=8)
    finally:
        j2.signal(signal.SIGCONT)
    result = client.result_of(future)
    # Before: "applied by 1 node(s)", /j2 live again and on that epoch, not named.
    assert result.success, result.message
    assert result.acknowledged == ("/j1", "/j2"), result.message
