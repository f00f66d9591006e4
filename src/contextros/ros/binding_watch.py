"""The manager's watch on what its bindings set: the ROS side of `contextros.bindings.actual`.

It listens to `/parameter_events` (rcl_interfaces/msg/ParameterEvent) and to each bound
lifecycle node's `<node>/transition_event` (lifecycle_msgs/msg/TransitionEvent). Any
process may publish those, so an event is only a hint: a bound parameter or node that an
event says changed is read from the node itself (`get_parameters`, `get_state`), and only
what the node answers counts. The reads, and the restores of bindings whose policy is
`restore`, run as the manager's switches do, in its worker thread, one job at a time and
never beside a switch (`LayerManagerNode` schedules them when no command waits).
"""

from __future__ import annotations

import time
from typing import Any

from lifecycle_msgs.msg import TransitionEvent
from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from rclpy.qos import qos_profile_parameter_events

from contextros.bindings.actual import ActualState, BindingKey, Drift, Reading
from contextros.bindings.inference import Inference, infer
from contextros.ros.bindings import PRIMARY_STATES, BindingDriver, BindingError, python_value
from contextros.ros.node_log import NodeLog

# What one event is read for at most (anyone can publish one): its node name's length and
# the parameters looked at.
MAX_NODE_NAME = 256
MAX_PARAMETERS_PER_EVENT = 64
# A bound parameter or node that could not be read (not up yet) is tried again this late.
RETRY_READ = 2.0
# How often the ROS graph is looked at for bound nodes that left or (re)appeared (seconds):
# a restarted lifecycle node publishes no transition, it is read when it appears.
GRAPH_LOOK = 1.0


class WatchJob:
    """Reads and restores done in the worker thread (`run`); the outcome stays here."""

    def __init__(self, reads: dict[BindingKey, float], restores: list[Drift]) -> None:
        self.reads = reads
        self.restores = restores
        self.unread: dict[BindingKey, str] = {}
        self.restored: list[tuple[Drift, str, bool]] = []  # drift, what happened, done

    def run(self, driver: BindingDriver) -> None:
        for key, noticed in self.reads.items():
            try:
                driver.read(key, noticed)
            except BindingError as error:
                self.unread[key] = str(error)
        for drift in self.restores:
            try:
                self.restored.append((drift, driver.set_back(drift.binding), True))
            except BindingError as error:
                self.restored.append((drift, str(error), False))


class BindingWatch:
    """The actual state of `driver`'s bindings on `node` (the manager): events in, reads
    and restores out as `WatchJob`s, an `infer` drift's switch from `inference`."""

    def __init__(self, node: Node, driver: BindingDriver, log: NodeLog) -> None:
        self.driver = driver
        self.log = log
        self.actual = ActualState(driver.bindings, driver.resolve)
        self._parameters = self.actual.parameters_of()
        # Keys to read, with when a change was first noticed and the value the event had.
        now = time.time()
        self._pending: dict[BindingKey, tuple[float, Any]] = {
            key: (now, _UNKNOWN) for key in self.actual.bound_keys()
        }
        self._retry_at = 0.0  # monotonic: when keys never read are tried again
        self._node = node
        # The bound nodes' event publishers (their gids) at the last look at the graph.
        self._endpoints: dict[tuple[str, bool], set[bytes]] | None = None
        self._graph_at = 0.0  # monotonic: the next look
        self._logged: set[tuple[int, float]] = set()  # drifts logged (binding, since)
        self._inferred = ""  # the last inference submitted or logged
        if self._parameters:
            node.create_subscription(
                ParameterEvent,
                "/parameter_events",
                self._on_parameter_event,
                qos_profile_parameter_events,
            )
        for lifecycle in sorted(self.actual.lifecycle_nodes()):
            node.create_subscription(
                TransitionEvent,
                f"{lifecycle}/transition_event",
                lambda msg, name=lifecycle: self._on_transition(name, msg),
                10,
            )

    # -- events: hints of a change ------------------------------------------------------

    def _on_parameter_event(self, msg: Any) -> None:
        node = msg.node
        if not isinstance(node, str) or len(node) > MAX_NODE_NAME:
            return
        names = self._parameters.get(node)
        if names is None:
            return
        now = time.time()
        changed = [*msg.new_parameters[:MAX_PARAMETERS_PER_EVENT]]
        changed += msg.changed_parameters[:MAX_PARAMETERS_PER_EVENT]
        for parameter in changed:
            if parameter.name in names:
                self._hint((node, parameter.name), now, python_value(parameter.value))
        for parameter in msg.deleted_parameters[:MAX_PARAMETERS_PER_EVENT]:
            if parameter.name in names:
                self._hint((node, parameter.name), now, None)

    def _on_transition(self, node: str, msg: Any) -> None:
        state = PRIMARY_STATES.get(msg.goal_state.id)
        if state is not None:  # (a transition state is followed by a primary one)
            self._hint((node, ""), time.time(), state)

    def _hint(self, key: BindingKey, now: float, value: Any) -> None:
        noticed = self._pending.get(key, (now, None))[0]
        self._pending[key] = (min(noticed, now), value)

    # -- jobs ---------------------------------------------------------------------------

    def next_job(self) -> WatchJob | None:
        """What to read or set back now (None: nothing): call it when no switch runs."""
        self.switched(changed=False)
        now = time.monotonic()
        if now >= self._graph_at:
            self._graph_at = now + GRAPH_LOOK
            self._look_at_graph()
        if now >= self._retry_at:
            self._retry_at = now + RETRY_READ
            for key in self.actual.bound_keys() - self.actual.readings.keys():
                self._pending.setdefault(key, (time.time(), _UNKNOWN))
        reads = {}
        for key, (noticed, value) in self._pending.items():
            reading = self.actual.readings.get(key)
            # An event showing what was read (a switch's own set, heard after it) is no news.
            if reading is None or value is _UNKNOWN or not _same(reading.value, value):
                reads[key] = noticed
        self._pending.clear()
        restores = self.actual.restore_due(now)
        for drift in self.actual.drifts():
            if drift.policy == "restore" and self.actual.given_up(drift.key):
                self._log_drift(drift, f"{self.actual.state(drift.index).action}")
        return WatchJob(reads, restores) if reads or restores else None

    def _look_at_graph(self) -> None:
        """A bound node whose event publisher left the graph has nothing (a drift, not set
        back: there is no one to set); one with a new publisher (it started, or restarted)
        is read."""
        # (node, its lifecycle state: not its parameters) -> its event publishers' gids
        endpoints: dict[tuple[str, bool], set[bytes]] = {}
        if self._parameters:
            for info in self._node.get_publishers_info_by_topic("/parameter_events"):
                name = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                if name in self._parameters:
                    endpoints.setdefault((name, False), set()).add(bytes(info.endpoint_gid))
        for lifecycle in self.actual.lifecycle_nodes():
            for info in self._node.get_publishers_info_by_topic(f"{lifecycle}/transition_event"):
                endpoints.setdefault((lifecycle, True), set()).add(bytes(info.endpoint_gid))
        before, self._endpoints = self._endpoints, endpoints
        if before is None:
            return
        wall = time.time()
        for key in self.actual.bound_keys():
            watched = (key[0], not key[1])
            now, then = endpoints.get(watched, set()), before.get(watched, set())
            if then and not now:
                gone = Reading(None, "(node not in the ROS graph)", wall, wall, absent=True)
                self.actual.read(key, gone)
            elif now - then:
                self._pending[key] = (wall, _UNKNOWN)

    def finished(self, job: WatchJob) -> None:
        """A job's outcome (executor thread)."""
        self.switched(changed=False)
        for drift, what, done in job.restored:
            if done:
                self.log.warning(
                    f"binding of layer {drift.layer} ({drift.binding.path}:"
                    f"{drift.binding.at.line}) did not hold: {drift.describe()} "
                    f"since {_clock(drift.since)}, changed by another node or client; {what} "
                    f"(on drift restore: at most {self.actual.restore_limit} times within "
                    f"{self.actual.restore_window:g} s)"
                )
                self.actual.acted(drift, f"set back at {_clock(time.time())}")
            else:
                self.log.error(f"binding of layer {drift.layer} not set back: {what}")
                self.actual.acted(drift, f"setting back failed: {what}")
        for drift in self.actual.drifts():
            if drift.policy == "report":
                self._log_drift(drift, "reported (on drift report)")

    def switched(self, changed: bool = True) -> None:
        """Take what the driver read and set; after a switch (`changed`), ROS reflects its
        configuration now, and what it set is what its layers set."""
        readings = self.driver.take_readings()
        for key, reading in readings:
            self.actual.read(key, reading)
        if changed or self.actual.applied != self.driver.applied:
            keys = [key for key, _ in readings] if changed else []
            self.actual.configuration(self.driver.applied, changed=keys)

    # -- inference ----------------------------------------------------------------------

    def inference(self, active: tuple[str, ...]) -> Inference | None:
        """A switch the `infer` drifts ask for, once per distinct inference (else None)."""
        inferred = infer(self.actual, active)
        drifts = [drift for drift in self.actual.drifts() if drift.policy == "infer"]
        if inferred is None:
            self._inferred = ""
            for drift in drifts:
                self._log_drift(
                    drift, "on drift infer: no other layer's bindings all hold; reported only"
                )
            return None
        if inferred.reason + ",".join(inferred.ambiguous) == self._inferred:
            return None
        self._inferred = inferred.reason + ",".join(inferred.ambiguous)
        if inferred.ambiguous:
            what = (
                f"on drift infer: layers {', '.join(inferred.ambiguous)} all match what the "
                "nodes have; reported only"
            )
        else:
            off = f", {', '.join(inferred.deactivate)} off" if inferred.deactivate else ""
            what = f"on drift infer: switching to {', '.join(inferred.activate)}{off}"
        for drift in drifts:
            self.actual.acted(drift, what.removeprefix("on drift infer: "))
            self._log_drift(drift, what)
        return None if inferred.ambiguous else inferred

    def _log_drift(self, drift: Drift, what: str) -> None:
        if (drift.index, drift.since) in self._logged:
            return
        self._logged.add((drift.index, drift.since))
        if len(self._logged) > 1000:  # bounded: a drift logged again after that is harmless
            self._logged.clear()
        self.log.warning(
            f"binding of layer {drift.layer} ({drift.binding.path}:{drift.binding.at.line}) "
            f"no longer holds: {drift.describe()} since {_clock(drift.since)}; {what}"
        )


_UNKNOWN = object()  # no value from an event: read it


def _same(a: Any, b: Any) -> bool:
    return type(a) is type(b) and a == b


def _clock(wall: float) -> str:
    return time.strftime("%H:%M:%S", time.gmtime(wall)) + f".{int(wall % 1 * 1000):03d} UTC"
