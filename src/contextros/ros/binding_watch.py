"""The manager's watch on what its bindings set: the ROS side of `contextros.bindings.actual`.

What the bound nodes have comes from `contextros.ros.graph_observer`, which reads the nodes
themselves (when they appear, and after each of their events: an event is only a hint,
any process may publish one), and says when a node left the graph. A read that was out
while the driver set something may be older than what it set: it is dropped and the node
read again. The restores of bindings whose policy is `restore` run as the manager's
switches do, in its worker thread, one job at a time and never beside a switch
(`LayerManagerNode` schedules them when no command waits).
"""

from __future__ import annotations

import time

from contextros.bindings.actual import ActualState, BindingKey, Drift, Reading
from contextros.bindings.inference import Inference, infer
from contextros.bindings.values import PRIMARY_STATES, lifecycle_state, plain_value
from contextros.ros.bindings import BindingDriver, BindingError, shown
from contextros.ros.graph_observer import GraphObserver, NodeRead
from contextros.ros.node_log import NodeLog

ABSENT = "(node not in the ROS graph)"


class WatchJob:
    """Restores done in the worker thread (`run`); the outcome stays here."""

    def __init__(self, restores: list[Drift]) -> None:
        self.restores = restores
        self.restored: list[tuple[Drift, str, bool]] = []  # drift, what happened, done

    def run(self, driver: BindingDriver) -> None:
        for drift in self.restores:
            try:
                self.restored.append((drift, driver.set_back(drift.binding), True))
            except BindingError as error:
                self.restored.append((drift, str(error), False))


class BindingWatch:
    """The actual state of `driver`'s bindings, from what `observer` reads of the nodes;
    restores out as `WatchJob`s, an `infer` drift's switch from `inference`."""

    def __init__(self, driver: BindingDriver, log: NodeLog, observer: GraphObserver) -> None:
        self.driver = driver
        self.log = log
        self.actual = ActualState(driver.bindings, driver.resolve)
        self._observer = observer
        # When the driver last read or set something (monotonic): a read asked before may
        # be older than that.
        self._driven_at = 0.0
        self._logged: set[tuple[int, float]] = set()  # drifts logged (binding, since)
        self._inferred = ""  # the last inference submitted or logged
        parameters = self.actual.parameters_of()
        observer.subscribe(self._on_read)
        observer.follow(sorted(self.actual.lifecycle_nodes()), parameters)

    # -- what the nodes have ------------------------------------------------------------

    def _on_read(self, read: NodeRead) -> None:
        if read.asked < self._driven_at and not read.absent:
            self._observer.refresh(read.node)
            return
        wall = time.time()
        if read.state:
            key: BindingKey = (read.node, "")
            if key in self.actual.bound_keys():
                self.actual.read(key, _state_reading(read, wall))
            return
        message = read.message
        for parameter in [*message.new_parameters, *message.deleted_parameters]:
            key = (read.node, parameter.name)
            if key not in self.actual.bound_keys():
                continue
            if read.absent:
                reading = Reading(None, ABSENT, wall, wall, absent=True)
            else:
                value = plain_value(parameter.value)[0]
                reading = Reading(value, shown(parameter.value), wall, read.noticed)
            self.actual.read(key, reading)

    # -- jobs ---------------------------------------------------------------------------

    def next_job(self) -> WatchJob | None:
        """What to set back now (None: nothing): call it when no switch runs."""
        self.switched(changed=False)
        restores = self.actual.restore_due(time.monotonic())
        for drift in self.actual.drifts():
            if drift.policy == "restore" and self.actual.given_up(drift.key):
                self._log_drift(drift, f"{self.actual.state(drift.index).action}")
        return WatchJob(restores) if restores else None

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
        if readings:
            self._driven_at = time.monotonic()
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


def _state_reading(read: NodeRead, wall: float) -> Reading:
    if read.absent:
        return Reading(None, ABSENT, wall, wall, absent=True)
    state_id = read.message.goal_state.id
    name = PRIMARY_STATES.get(state_id) or f"in transition ({lifecycle_state(state_id) or '?'})"
    return Reading(name, name, wall, read.noticed)


def _clock(wall: float) -> str:
    return time.strftime("%H:%M:%S", time.gmtime(wall)) + f".{int(wall % 1 * 1000):03d} UTC"
