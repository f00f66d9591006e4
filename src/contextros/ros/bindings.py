"""Layers that drive ROS, carried out by the Layer manager over standard ROS services.

`parameter` declarations go through `/<node>/get_parameters` and `/<node>/set_parameters`
(rcl_interfaces), `lifecycle` declarations through `/<node>/get_state` and
`/<node>/change_state` (lifecycle_msgs): every ROS 2 node has the former, every managed node
the latter, so the nodes need to know nothing of ContextROS and may be C++.

A switch runs in a worker thread (blocking on the answers while the manager's executor
keeps spinning and delivers them), and either completes or is rolled back: a parameter a
node rejects, a node that does not answer, or a failed lifecycle transition undoes what the
switch already did, in reverse order, and names node, parameter or transition and the reason.
A call not answered in time has an unknown outcome: the node is read afterwards and given
back what it had, and the message says what was found and done. What to give back is on
disk before anything changes (`contextros.ros.binding_memory`); the calls and their time
limits are `contextros.ros.node_calls`.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from contextros_interfaces.msg import BindingInfo
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node

from contextros.bindings import Bindings, LifecycleChange, ParameterChange, Plan, transitions
from contextros.bindings.actual import ActualState, BindingKey, Reading
from contextros.bindings.values import NOT_SET, plain_value
from contextros.language.bindings import LifecycleBinding, ParameterBinding
from contextros.ros.binding_memory import BindingMemory, BindingMemoryFile, Configuration
from contextros.ros.messages import seconds_to_stamp
from contextros.ros.node_calls import CALL_TIMEOUT as CALL_TIMEOUT
from contextros.ros.node_calls import BindingError as BindingError
from contextros.ros.node_calls import CallTimedOut as CallTimedOut
from contextros.ros.node_calls import Deadline as Deadline
from contextros.ros.node_calls import InTransition as InTransition
from contextros.ros.node_calls import NodeCalls
from contextros.ros.node_calls import shown as shown
from contextros.ros.node_calls import to_parameter_value as to_parameter_value


class BindingDriver(NodeCalls):
    """Applies a `Bindings` plan from one configuration to the next, with rollback."""

    def __init__(
        self,
        node: Node,
        bindings: Bindings,
        *,
        call_timeout: float = CALL_TIMEOUT,
        discovery_time: float = 5.0,
        memory: Path | None = None,
    ) -> None:
        super().__init__(node, call_timeout, discovery_time)
        self.bindings = bindings
        # The configuration ROS reflects, the values and states to give back, and what a
        # switch may have left half-done (binding_memory says the invariants).
        self.kept = BindingMemory()
        # (node, parameter or "" for lifecycle) -> the last result of applying it.
        self._results: dict[tuple[str, str], BindingResult] = {}
        # What the switches read and set on the nodes, for the actual state (`take_readings`).
        self._readings: list[tuple[BindingKey, Reading]] = []
        # Where `kept` is across restarts (next to the state file).
        self.memory = memory
        self._file = BindingMemoryFile(memory) if memory is not None else None
        self._load()
        # Discovery of a service takes a while (seconds on a loaded machine): the clients
        # exist from the start, so the first switch does not wait for it.
        for name in sorted({self.resolve(b.node) for b in bindings.parameters}):
            self._client(name, "get_parameters", GetParameters)
            self._client(name, "set_parameters", SetParameters)
        for name in sorted({self.resolve(b.node) for b in bindings.lifecycles}):
            self._client(name, "get_state", GetState)
            self._client(name, "change_state", ChangeState)

    @property
    def applied(self) -> Configuration:
        """The configuration ROS was last brought to completely."""
        return self.kept.applied

    @property
    def unsettled(self) -> bool:
        """Whether ROS may be partly elsewhere (a switch killed halfway, a rollback that
        failed): then even a switch to `applied` has work to do (`plan`)."""
        return bool(self.kept.unsettled)

    def settled(self, configuration: Sequence[str]) -> None:
        """ROS reflects `configuration` (its plan from here is empty)."""
        self.kept.applied, self.kept.unsettled = tuple(configuration), ()
        self._save()

    # -- memory across restarts ---------------------------------------------------------

    def _load(self) -> None:
        """Take `kept` from the file; a damaged file is logged and ignored (the values in
        place are then taken for the originals, as without one)."""
        if self._file is None:
            return
        try:
            loaded = self._file.load()
        except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
            self.node.get_logger().error(
                f"ignored {self._file.path} (values to restore from before the last restart): "
                f"{error!r}"
            )
            return
        if loaded is not None:
            self.kept = loaded
        if self.kept.unsettled:
            self.node.get_logger().warning(
                f"{self._file.path}: the last switch of the layers' parameters and lifecycle "
                "states did not end (the manager stopped during it): the nodes are brought "
                "to the recovered state, what the layers changed given back"
            )

    def _save(self) -> None:
        if self._file is None:
            return
        try:
            self._file.save(self.kept)
        except OSError as error:
            self.node.get_logger().error(f"{self._file.path} not written: {error}")

    # -- names --------------------------------------------------------------------------

    def resolve(self, name: str) -> str:
        """A declared node name, fully qualified: relative names in the manager's namespace."""
        if name.startswith("/"):
            return name
        namespace = self.node.get_namespace().rstrip("/")
        return f"{namespace}/{name.removeprefix('~/')}"

    def plan(self, old: Sequence[str], new: Sequence[str]) -> Plan:
        """The changes from `old` to `new`; with ROS unsettled, also those from each
        configuration it may be partly at (what any of them touched is set or restored)."""
        plans = [self.bindings.plan(c, new, self.resolve) for c in (old, *self.kept.unsettled)]
        if len(plans) == 1:
            return plans[0]
        return Plan(
            tuple(
                sorted(
                    {change for p in plans for change in p.parameters},
                    key=lambda c: (not c.restore, c.node, c.name),
                )
            ),
            tuple(
                sorted(
                    {change for p in plans for change in p.lifecycles},
                    key=lambda c: (not c.restore, c.node),
                )
            ),
        )

    # -- the switch (worker thread) -----------------------------------------------------

    def switch(
        self, old: Sequence[str], new: Sequence[str], deadline: Deadline | None = None
    ) -> None:
        """Make ROS reflect `new` (coming from `old`), each call over by `deadline`;
        BindingError, rolled back, if not (its message says what was undone and how)."""
        plan = self.plan(old, new)
        undo: list[_Undo] = []
        # The originals are forgotten only once the whole switch succeeded: a restore that
        # fails, or one a later step rolls back, must find them again next time.
        originals = _Originals()
        unsettled_before = self.kept.unsettled
        if tuple(new) not in unsettled_before:
            # On disk before the first change (`_write_ahead`): killed halfway, a restarted
            # manager knows ROS may be partly at `new`.
            self.kept.unsettled = (*unsettled_before, tuple(new))
        self._deadline = deadline
        try:
            for change in plan.parameters:
                self._parameter(change, undo, originals)
            for lifecycle in plan.lifecycles:
                self._lifecycle(lifecycle, undo, originals)
        except BindingError as error:
            self._deadline = None  # a rollback takes what it needs
            complete, notes = self._roll_back(undo)
            if complete:
                # Everything is as before: what this switch read first is read again.
                self._forget(originals.read)
                self.kept.unsettled = unsettled_before
            self._save()
            raise BindingError(
                _failure(str(error), isinstance(error, CallTimedOut), complete, notes)
            ) from None
        finally:
            self._deadline = None
        self._forget(originals.restored)
        self.kept.applied, self.kept.unsettled = tuple(new), ()
        self._save()

    def _write_ahead(self) -> None:
        """Before a change: the file has what to give back, and that a switch is under way."""
        self._save()

    def _forget(self, keys: list[tuple[str, Any]]) -> None:
        for kind, key in keys:
            if kind == "parameter":
                self.kept.parameters.pop(key, None)
            else:
                self.kept.states.pop(key, None)

    def _roll_back(self, undo: list[_Undo]) -> tuple[bool, list[str]]:
        """Undo `undo` in reverse order: whether all of it was, and what to say about the
        steps whose outcome was unknown and those that failed (logged too)."""
        complete, notes = True, []
        for step in reversed(undo):
            try:
                note = self._undo(step)
            except BindingError as error:
                complete = False
                self.node.get_logger().error(f"rolling back: {error}")
                notes.append(f"not undone: {error}")
            else:
                if note:
                    notes.append(note)
        return complete, notes

    def _undo(self, step: _Undo) -> str:
        """Undo one step; what to say about it ("" for a step whose outcome was known)."""
        if isinstance(step, _ParameterBack):
            if step.unknown:
                return self._parameter_back(step.node, step.name, step.previous)
            self._set(step.node, step.name, step.previous)
            self._seen((step.node, step.name), step.previous)
            self._put_back((step.node, step.name), shown(step.previous))
            return ""
        if step.timed_out:
            return self._state_back(step.node, step.previous, step.timed_out)
        for transition_id, label in step.path:
            self._change_state(step.node, transition_id, label)
        self._seen((step.node, ""), self._get_state(step.node))
        self._put_back((step.node, ""), step.previous)
        return ""

    def _put_back(self, key: tuple[str, str], value: str) -> None:
        """`status` shows that a set rolled back is no longer in place."""
        text = f"put back to {value} (the switch failed)"
        self._results[key] = BindingResult(True, text, time.time())

    def _parameter(self, change: ParameterChange, undo: list[_Undo], originals: _Originals) -> None:
        key = change.key
        current = self._get(change.node, change.name)
        self._seen(key, current)
        if key not in self.kept.parameters:
            self.kept.parameters[key] = current
            originals.read.append(("parameter", key))
        if change.restore:
            target = self.kept.parameters[key]
            originals.restored.append(("parameter", key))
            if target.type == NOT_SET:
                return  # it had no value before: leave the last one
        else:
            target = to_parameter_value(change.value, like=current)
        self._write_ahead()
        with self._outcome((change.node, change.name), change, shown(target)):
            try:
                self._set(change.node, change.name, target, change.layer)
            except CallTimedOut:
                undo.append(_ParameterBack(change.node, change.name, current, unknown=True))
                raise
        self._seen(key, target)
        undo.append(_ParameterBack(change.node, change.name, current))

    def _lifecycle(self, change: LifecycleChange, undo: list[_Undo], originals: _Originals) -> None:
        current = self._get_state(change.node)
        self._seen((change.node, ""), current)
        if change.node not in self.kept.states:
            self.kept.states[change.node] = current
            originals.read.append(("lifecycle", change.node))
        if change.restore:
            wanted: str | None = self.kept.states[change.node]
            originals.restored.append(("lifecycle", change.node))
        else:
            wanted = change.state
        assert wanted is not None
        try:
            path = transitions(current, wanted)
        except ValueError as error:
            raise BindingError(f"lifecycle node {change.node}: {error}") from None
        if path:
            self._write_ahead()
        done: list[tuple[int, str]] = []
        with self._outcome((change.node, ""), change, wanted):
            for transition_id, label in path:
                try:
                    self._change_state(change.node, transition_id, label, change.layer, current)
                except CallTimedOut:
                    undo.append(_StateBack(change.node, current, (), label))
                    raise
                except BindingError:
                    if done:
                        undo.append(_StateBack(change.node, current, _reverse(done)))
                    raise
                done.append((transition_id, label))
        self._seen((change.node, ""), wanted)
        if done:
            undo.append(_StateBack(change.node, current, _reverse(done)))

    # -- a call whose outcome is unknown ------------------------------------------------

    def _parameter_back(self, node: str, name: str, previous: Any) -> str:
        """After a set of `name` timed out: read what the node has, and set `previous`
        again if it is not that; what was found and done."""
        value = self.read_after_a_timeout(lambda: self._get(node, name))
        self._seen((node, name), value)
        if value == previous:
            return f"{node} still had {name} = {shown(previous)}"
        self._set(node, name, previous)
        self._seen((node, name), previous)
        return f"{node} had {name} = {shown(value)}: set back to {shown(previous)}"

    def _state_back(self, node: str, previous: str, after: str) -> str:
        """After transition `after` of lifecycle node `node` timed out: read its state
        (waiting while it is in a transition) and bring it back to `previous`; what was
        found and done. BindingError, naming the state the node is left in, if it cannot."""
        try:
            state = self.read_after_a_timeout(lambda: self._get_state(node))
        except InTransition as error:
            raise BindingError(f"{error}: left there (it was {previous} before {after})") from None
        except BindingError as error:
            raise BindingError(
                f"{error}: its state is unknown (it was {previous} before {after})"
            ) from None
        self._seen((node, ""), state)
        if state == previous:
            return f"lifecycle node {node} was still {previous}"
        try:
            path = transitions(state, previous)
        except ValueError as error:
            raise BindingError(f"lifecycle node {node} is left {state}: {error}") from None
        for transition_id, label in path:
            try:
                self._change_state(node, transition_id, label, current=state)
            except BindingError as error:
                raise BindingError(f"{error}: lifecycle node {node} is left {state}") from None
        self._seen((node, ""), previous)
        labels = ", ".join(label for _, label in path)
        return f"lifecycle node {node} was {state}: brought back to {previous} ({labels})"

    # -- the actual state: what the nodes have (contextros.bindings.actual) -------------

    def _seen(self, key: BindingKey, value: Any) -> None:
        """Record what node and parameter `key` has: a ParameterValue, or a lifecycle state."""
        wall = time.time()
        if isinstance(value, str):
            reading = Reading(value, value, wall, wall)
        else:
            reading = Reading(plain_value(value)[0], shown(value), wall, wall)
        with self._lock:
            self._readings.append((key, reading))

    def take_readings(self) -> list[tuple[BindingKey, Reading]]:
        """What was read or set since the last call (in that order)."""
        with self._lock:
            readings, self._readings = self._readings, []
        return readings

    def set_back(self, binding: ParameterBinding | LifecycleBinding) -> str:
        """Give the node back what `binding` sets (its policy is `restore`); what was done,
        for the log. BindingError if the node refuses or does not answer."""
        node = self.resolve(binding.node)
        if isinstance(binding, ParameterBinding):
            current = self._get(node, binding.name)
            target = to_parameter_value(binding.value, like=current)
            self._set(node, binding.name, target, binding.layer.name)
            self._seen((node, binding.name), target)
            return f"set {node} {binding.name} from {shown(current)} back to {shown(target)}"
        current = self._get_state(node)
        try:
            path = transitions(current, binding.state)
        except ValueError as error:
            raise BindingError(f"lifecycle node {node}: {error}") from None
        for transition_id, label in path:
            self._change_state(node, transition_id, label, binding.layer.name, current)
        self._seen((node, ""), binding.state)
        labels = ", ".join(label for _, label in path)
        return f"brought lifecycle node {node} from {current} back to {binding.state} ({labels})"

    # -- what happened, for `status` and the dashboard -----------------------------------

    @contextlib.contextmanager
    def _outcome(
        self, key: tuple[str, str], change: ParameterChange | LifecycleChange, value: str
    ) -> Iterator[None]:
        verb = "restored to" if change.restore else "set to"
        by = f" for {change.layer}" if change.layer else ""
        try:
            yield
        except BindingError as error:
            self._results[key] = BindingResult(False, str(error), time.time())
            raise
        self._results[key] = BindingResult(True, f"{verb} {value}{by}", time.time())

    def infos(self, actual: ActualState | None = None) -> list[Any]:
        """Every declaration with the last result of applying it (BindingInfo messages),
        and with `actual`, what was read on the node and whether it drifted."""
        results = dict(self._results)
        declared = [
            (p.layer.name, "parameter", p.node, p.name, _shown_value(p.value), p.path, p.at)
            for p in self.bindings.parameters
        ] + [
            (c.layer.name, "lifecycle", c.node, "", c.state, c.path, c.at)
            for c in self.bindings.lifecycles
        ]
        policies = [b.policy for b in self.bindings.parameters]
        policies += [b.policy for b in self.bindings.lifecycles]
        infos = []
        for index, (layer, kind, declared_node, parameter, value, path, at) in enumerate(declared):
            node = self.resolve(declared_node)
            info = BindingInfo(
                layer=layer,
                kind=kind,
                node=node,
                parameter=parameter,
                value=value,
                where=f"{path}:{at.line}:{at.col}",
            )
            result = results.get((node, parameter))
            if result is not None:
                info.ok, info.last_result = result.ok, result.text
                info.last_time = seconds_to_stamp(result.wall)
            info.policy = policies[index]
            if actual is not None:
                _fill_actual(info, actual, index)
            infos.append(info)
        return infos


@dataclass(frozen=True)
class BindingResult:
    ok: bool
    text: str
    wall: float


def _shown_value(value: Any) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else repr(value)


@dataclass(frozen=True)
class _ParameterBack:
    """A parameter a switch set (or may have: `unknown`), and the value it had before."""

    node: str
    name: str
    previous: Any
    unknown: bool = False


@dataclass(frozen=True)
class _StateBack:
    """A lifecycle node a switch moved from `previous`, and the transitions back; or, when
    transition `timed_out` was not answered in time, the node to read and bring back."""

    node: str
    previous: str
    path: Sequence[tuple[int, str]]
    timed_out: str = ""


_Undo = _ParameterBack | _StateBack


def _failure(error: str, timed_out: bool, complete: bool, notes: list[str]) -> str:
    """A failed switch's message: what failed, and what became of what it had changed."""
    if complete and not timed_out:
        return f"{error}; nothing changed"
    done = "; ".join(notes)
    if complete:
        return (
            f"{error}, so whether it did is unknown: {done}; everything the command changed "
            "is undone, no state published"
        )
    unknown = ", so whether it did is unknown" if timed_out else ""
    return (
        f"{error}{unknown}; rolled back only in part ({done}); no state published, the "
        "manager tries again to bring the nodes to the published state"
    )


@dataclass
class _Originals:
    """What one switch did to the remembered originals: first read, and restored."""

    read: list[tuple[str, Any]] = field(default_factory=list)
    restored: list[tuple[str, Any]] = field(default_factory=list)


def _fill_actual(info: Any, actual: ActualState, index: int) -> None:
    state = actual.state(index)
    info.in_force, info.holds = state.in_force, state.holds
    if state.reading is not None:
        info.observed = state.reading.shown
        info.observed_time = seconds_to_stamp(state.reading.wall)
    if state.drifted_since is not None:
        info.drifted = True
        info.drifted_since = seconds_to_stamp(state.drifted_since)
        info.drift_action = state.action


_REVERSE = {
    "configure": (2, "cleanup"),
    "activate": (4, "deactivate"),
    "deactivate": (3, "activate"),
    "cleanup": (1, "configure"),
}


def _reverse(done: list[tuple[int, str]]) -> list[tuple[int, str]]:
    return [_REVERSE[label] for _, label in reversed(done)]
