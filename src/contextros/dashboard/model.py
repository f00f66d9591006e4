"""What the dashboard shows, per robot namespace, fed with plain values (no ROS inside).

Every collection is bounded: the epoch history keeps the last `HISTORY` switches, a node
that leaves or stays silent is dropped after `FORGET_AFTER` seconds, so a page left open
for hours costs what it cost after a minute.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from contextros.protocol.events import ParticipantReport
from contextros.protocol.relations import LayerDeclaration, implied_by

HISTORY = 50  # switches kept per robot
FORGET_AFTER = 60.0  # seconds a silent node stays on the page (greyed out)
LIVENESS = 3.0  # a node silent this long is shown as silent (the manager's default bound)
HEARTBEAT_LOST = 2.0  # the manager's heartbeat is repeated every 0.25 s
# Anyone in the domain can publish statuses: at most this many nodes per robot (the least
# recently heard go first), and texts cut to this length.
MAX_NODES = 1000
MAX_TEXT = 300

Snapshot = dict[str, Any]


@dataclass
class _Switch:
    epoch: int
    active: tuple[str, ...]
    requester: str
    reason: str
    published: float  # the state's stamp (the manager's wall clock)
    latency_ms: dict[str, float] = field(default_factory=dict)  # node -> applied after


@dataclass
class _Node:
    name: str
    language: str = ""
    layers: tuple[str, ...] = ()
    applied_epoch: int = 0
    critical: bool = False
    pending_epoch: int = 0
    failed_epoch: int = 0
    error: str = ""
    manager_lost: bool = False
    hosted: tuple[str, ...] = ()
    heard: float = 0.0  # wall clock of its last status
    joined: float = 0.0  # the stamp of its first status: switches before it are not its
    applied_stamp: float = 0.0  # the stamp of the status that reported its newest epoch
    left: bool = False


@dataclass
class _Robot:
    namespace: str
    epoch: int = 0
    active: tuple[str, ...] = ()
    requester: str = ""
    reason: str = ""
    manager_id: str = ""
    heartbeat: float = 0.0  # wall clock of the manager's last heartbeat or state
    history: deque[_Switch] = field(default_factory=lambda: deque(maxlen=HISTORY))
    nodes: dict[str, _Node] = field(default_factory=dict)
    registry: Snapshot = field(default_factory=dict)  # the last answer of the query service
    registry_at: float = 0.0


class DashboardModel:
    """Thread-safe: the ROS side writes, the web server reads `snapshot()`; `on_change` is
    called (from the writer's thread) after each change."""

    def __init__(
        self,
        namespaces: Iterable[str],
        on_change: Callable[[], object] = lambda: None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        import time

        self._clock = clock or time.time
        self._robots = {ns: _Robot(ns) for ns in namespaces}
        self._lock = threading.Lock()
        self.on_change = on_change
        self.version = 0

    def _changed(self) -> None:
        self.version += 1
        self.on_change()

    # -- input ----------------------------------------------------------------------------

    def state(
        self,
        namespace: str,
        epoch: int,
        active: Iterable[str],
        requester: str,
        reason: str,
        stamp: float,
        manager_id: str,
        heartbeat: bool = False,
    ) -> None:
        """A state (or a heartbeat repeating it) from the manager of `namespace`."""
        with self._lock:
            robot = self._robots[namespace]
            robot.heartbeat = self._clock()
            if epoch <= robot.epoch and manager_id == robot.manager_id:
                if not heartbeat:
                    return
                self._changed()  # a heartbeat: only the manager's liveness changed
                return
            if epoch == 0:  # a manager still recovering has no state yet
                return
            robot.epoch, robot.active = epoch, tuple(active)
            robot.requester, robot.reason, robot.manager_id = requester, reason, manager_id
            if not robot.history or robot.history[-1].epoch != epoch:
                switch = _Switch(epoch, robot.active, requester, reason, stamp)
                for node in robot.nodes.values():  # a status may overtake its state
                    if node.applied_epoch >= epoch and node.applied_stamp >= stamp:
                        latency = (node.applied_stamp - stamp) * 1000
                        switch.latency_ms[node.name] = round(latency, 2)
                robot.history.append(switch)
            self._changed()

    def status(
        self, namespace: str, report: ParticipantReport, *, language: str, stamp: float
    ) -> None:
        """A participant's status message (`stamp`: when it sent it, its wall clock)."""
        node, applied_epoch = report.node, report.applied_epoch
        with self._lock:
            robot = self._robots[namespace]
            entry = robot.nodes.get(node) or _Node(node, joined=stamp)
            newly_applied = applied_epoch > entry.applied_epoch
            entry.language = language[:MAX_TEXT]
            entry.layers = tuple(layer.name for layer in report.layers)
            entry.applied_epoch = max(entry.applied_epoch, applied_epoch)
            entry.critical, entry.pending_epoch = report.in_critical_section, report.pending_epoch
            entry.failed_epoch, entry.error = report.failed_epoch, report.error[:MAX_TEXT]
            entry.manager_lost, entry.hosted = report.manager_lost, report.hosted
            entry.heard, entry.left = self._clock(), report.leaving
            robot.nodes[node] = entry
            if newly_applied:
                entry.applied_stamp = stamp
                for switch in robot.history:
                    if (
                        switch.epoch <= applied_epoch
                        and node not in switch.latency_ms
                        and switch.published >= entry.joined
                    ):
                        switch.latency_ms[node] = round((stamp - switch.published) * 1000, 2)
            self._forget(robot)
            self._changed()

    def registry(self, namespace: str, answer: Snapshot) -> None:
        """The manager's answer to a query (`contextros status --json`'s content)."""
        with self._lock:
            robot = self._robots[namespace]
            robot.registry, robot.registry_at = answer, self._clock()
            self._changed()

    def _forget(self, robot: _Robot) -> None:
        now = self._clock()
        for name in [n for n, e in robot.nodes.items() if now - e.heard > FORGET_AFTER]:
            del robot.nodes[name]
        if len(robot.nodes) > MAX_NODES:
            by_age = sorted(robot.nodes.values(), key=lambda e: e.heard)
            for entry in by_age[: len(robot.nodes) - MAX_NODES]:
                del robot.nodes[entry.name]

    # -- output ---------------------------------------------------------------------------

    def snapshot(self) -> Snapshot:
        with self._lock:
            now = self._clock()
            return {
                "version": self.version,
                "time": now,
                "robots": [self._robot(robot, now) for robot in self._robots.values()],
            }

    def _robot(self, robot: _Robot, now: float) -> Snapshot:
        registry = robot.registry
        known = {p["node"]: p for p in registry.get("participants", [])}
        implies = _declared_implies(registry)
        silent = robot.heartbeat == 0.0 or now - robot.heartbeat > HEARTBEAT_LOST
        return {
            "namespace": robot.namespace,
            "epoch": robot.epoch,
            "active": list(robot.active),
            # Each active layer another active layer implies: {"Propulsion": ["Flight"]}.
            "implied_by": _implied_by(robot.active, implies),
            "requester": robot.requester,
            "reason": robot.reason,
            "manager_id": robot.manager_id,
            "manager": {
                "heard_ago": None if robot.heartbeat == 0.0 else round(now - robot.heartbeat, 2),
                "silent": silent,
                "lost_by": sorted(n.name for n in robot.nodes.values() if n.manager_lost),
                "recovering": bool(registry.get("recovering", False)),
            },
            "history": [
                {
                    "epoch": s.epoch,
                    "active": list(s.active),
                    "implied_by": _implied_by(s.active, implies),
                    "requester": s.requester,
                    "reason": s.reason,
                    "published": s.published,
                    "latency_ms": dict(sorted(s.latency_ms.items())),
                }
                for s in reversed(robot.history)
            ],
            "nodes": [
                self._node(node, robot, known.get(node.name, {}), now)
                for node in sorted(robot.nodes.values(), key=lambda n: n.name)
            ],
            "rules": registry.get("rules", []),
            "bindings": registry.get("bindings", []),
            # The layers whose bindings all hold on the nodes: target (`active`) vs actual.
            "actual": registry.get("actual", []),
            "layers": registry.get("layers", []),
            "conflicts": registry.get("conflicts", []),
            "registry_age": None if not robot.registry_at else round(now - robot.registry_at, 2),
        }

    @staticmethod
    def _node(node: _Node, robot: _Robot, known: Snapshot, now: float) -> Snapshot:
        lag = max(0, robot.epoch - node.applied_epoch)
        if node.left:
            state = "left"
        elif now - node.heard > LIVENESS:
            state = "silent"
        elif known.get("conflict"):
            state = "twin"
        elif node.error and node.failed_epoch:
            state = "failed"
        elif lag:
            state = "lags"
        else:
            state = "ok"
        return {
            "node": node.name,
            "language": node.language or "?",
            "layers": list(node.layers),
            "applied_epoch": node.applied_epoch,
            "lag": lag,
            "state": state,
            "critical": node.critical,
            "pending_epoch": node.pending_epoch,
            "error": node.error,
            "manager_lost": node.manager_lost,
            "hosted": list(node.hosted),
            "heard_ago": round(now - node.heard, 2),
        }


def _declared_implies(registry: Snapshot) -> dict[str, LayerDeclaration]:
    """The layers' `implies` as the manager's last registry answer gives them."""
    return {
        str(layer["name"]): LayerDeclaration(
            str(layer["name"]), implies=frozenset(map(str, layer.get("implies", ())))
        )
        for layer in registry.get("layers", [])
        if isinstance(layer, dict) and "name" in layer
    }


def _implied_by(
    active: Iterable[str], declarations: dict[str, LayerDeclaration]
) -> dict[str, list[str]]:
    return {name: list(by) for name, by in implied_by(active, declarations).items()}
