"""The dashboard's model, fed by hand: latencies, node states, bounds (no ROS)."""

from __future__ import annotations

from typing import Any

from contextros.dashboard import model as dashboard
from contextros.dashboard.model import DashboardModel
from contextros.protocol.events import ParticipantReport
from contextros.protocol.relations import LayerDeclaration


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def status(m: DashboardModel, node: str, epoch: int, stamp: float, **extra: Any) -> None:
    language = extra.pop("language", "C++")
    layers = (LayerDeclaration("Indoor"), LayerDeclaration("Outdoor"))
    report = ParticipantReport(node, "i", layers, applied_epoch=epoch, **extra)
    m.status("/r1", report, language=language, stamp=stamp)


def test_each_switch_gets_each_nodes_latency_whichever_message_comes_first() -> None:
    clock = Clock()
    changes: list[int] = []
    m = DashboardModel(["/r1"], on_change=lambda: changes.append(1), clock=clock)
    status(m, "/a", 0, stamp=999.0)
    status(m, "/b", 0, stamp=999.0)
    m.state("/r1", 3, ["Indoor"], "op", "before /late joined", stamp=999.5, manager_id="m")
    status(m, "/late", 3, stamp=999.9)  # a join, not a switch's latency
    m.state("/r1", 4, ["Indoor"], "rule Gps", "no fix", stamp=1000.0, manager_id="m")
    status(m, "/a", 4, stamp=1000.004)
    status(m, "/b", 5, stamp=1000.020)  # overtakes the state of epoch 5
    m.state("/r1", 5, ["Outdoor"], "rule Gps", "fix", stamp=1000.010, manager_id="m")
    snapshot = m.snapshot()["robots"][0]
    assert [s["epoch"] for s in snapshot["history"]] == [5, 4, 3]
    assert snapshot["history"][0]["latency_ms"] == {"/b": 10.0}
    assert snapshot["history"][1]["latency_ms"] == {"/a": 4.0, "/b": 20.0}
    assert "/late" not in snapshot["history"][2]["latency_ms"]
    nodes = {n["node"]: n for n in snapshot["nodes"]}
    assert (nodes["/a"]["state"], nodes["/a"]["lag"]) == ("lags", 1)
    assert (nodes["/b"]["state"], nodes["/b"]["language"]) == ("ok", "C++")
    assert len(changes) == 8


def test_silent_twin_and_failed_nodes_and_a_silent_manager() -> None:
    clock = Clock()
    m = DashboardModel(["/r1"], clock=clock)
    m.state("/r1", 2, ["Indoor"], "op", "", stamp=1000.0, manager_id="m")
    status(m, "/twin", 2, stamp=1000.0)
    status(m, "/broken", 1, stamp=1000.0, failed_epoch=2, error="hook raised")
    status(m, "/quiet", 2, stamp=1000.0)
    m.registry("/r1", {"participants": [{"node": "/twin", "conflict": True}], "rules": []})
    clock.now += 1.0
    status(m, "/twin", 2, stamp=1001.0)
    status(m, "/broken", 1, stamp=1001.0, failed_epoch=2, error="hook raised")
    clock.now += 2.5  # /quiet last heard 3.5 s ago; the manager as long
    robot = m.snapshot()["robots"][0]
    states = {n["node"]: n["state"] for n in robot["nodes"]}
    assert states == {"/broken": "failed", "/quiet": "silent", "/twin": "twin"}
    assert robot["manager"]["silent"] and robot["manager"]["heard_ago"] == 3.5


def test_what_anyone_can_publish_is_bounded() -> None:
    clock = Clock()
    m = DashboardModel(["/r1"], clock=clock)
    for epoch in range(1, 500):
        m.state("/r1", epoch, ["Indoor"], "x", "", stamp=1000.0, manager_id="m")
    for index in range(dashboard.MAX_NODES + 200):
        clock.now += 0.001
        status(m, f"/n{index}", 1, stamp=clock.now, error="e" * 10_000)
    robot = m.snapshot()["robots"][0]
    assert len(robot["history"]) == dashboard.HISTORY
    assert len(robot["nodes"]) == dashboard.MAX_NODES
    assert robot["nodes"][0]["node"] == "/n1000"  # the least recently heard went first
    assert max(len(n["error"]) for n in robot["nodes"]) == dashboard.MAX_TEXT
    clock.now += dashboard.FORGET_AFTER + 1
    status(m, "/late", 1, stamp=clock.now)
    assert [n["node"] for n in m.snapshot()["robots"][0]["nodes"]] == ["/late"]
