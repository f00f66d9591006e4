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
disk before anything changes (`contextros.ros.binding_memory`).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from contextros_interfaces.msg import BindingInfo
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.msg import Parameter, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node

from contextros.bindings import Bindings, LifecycleChange, ParameterChange, Plan, transitions
from contextros.bindings.actual import ActualState, BindingKey, Reading
from contextros.bindings.values import (
    NOT_SET,
    PRIMARY_STATES,
    parameter_fields,
    plain_value,
    shown_parameter,
)
from contextros.language.bindings import LifecycleBinding, ParameterBinding
from contextros.language.bindings import ParameterValue as Value
from contextros.ros.binding_memory import BindingMemory, BindingMemoryFile, Configuration
from contextros.ros.messages import seconds_to_stamp

_MAX_REASON = 300
# Each call waits this long for its answer unless told otherwise (`--binding-timeout`):
# real drivers may take seconds to configure or activate.
CALL_TIMEOUT = 10.0
# How long a call waits for the node's service to be in the ROS graph (a node that is
# down), beyond the first seconds after the start while services are still being discovered.
SERVICE_WAIT = 2.0
# A node that did not answer in time may still be busy with that request: it is read again
# (to learn what happened) for up to this many call timeouts, while it is in a transition too.
PATIENCE_AFTER_A_TIMEOUT = 3
_POLL = 0.1  # seconds between reads of a node caught in a lifecycle transition
T = TypeVar("T")


class BindingError(Exception):
    """A switch's ROS side could not be done; the message says why and what was undone."""


class CallTimedOut(BindingError):
    """A request went out and no answer came in time: whether the node did it is unknown."""


class InTransition(BindingError):
    """A lifecycle node answered with a transition state (configuring, activating, ...)."""


@dataclass(frozen=True)
class Deadline:
    """The moment (monotonic) by which a command's calls must be over, and why, for messages."""

    at: float
    why: str


def _printable(text: str) -> str:
    """A reason that came from another node, fit for a message: printable, bounded."""
    clean = "".join(c if c.isprintable() else "?" for c in str(text))
    return clean if len(clean) <= _MAX_REASON else clean[:_MAX_REASON] + "..."


def to_parameter_value(value: Value | None, like: Any = None) -> Any:
    """A ParameterValue message; an integer goes to a double parameter as a double."""
    kind, field_name, plain = parameter_fields(value, NOT_SET if like is None else like.type)
    message = ParameterValue(type=kind)
    if field_name:
        setattr(message, field_name, plain)
    return message


shown = shown_parameter  # a ParameterValue as text, for messages


class BindingDriver:
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
        self.node = node
        self.bindings = bindings
        self.call_timeout = call_timeout
        # Until this (monotonic) time, a node's services may still be being discovered: a
        # call waits for them until then, not just `SERVICE_WAIT`.
        self.discovered_by = time.monotonic() + discovery_time
        # The configuration ROS reflects, the values and states to give back, and what a
        # switch may have left half-done (binding_memory says the invariants).
        self.kept = BindingMemory()
        self._clients: dict[tuple[str, str], Any] = {}
        # (node, parameter or "" for lifecycle) -> the last result of applying it.
        self._results: dict[tuple[str, str], BindingResult] = {}
        # What the switches read and set on the nodes, for the actual state (`take_readings`).
        self._readings: list[tuple[BindingKey, Reading]] = []
        self._lock = threading.Lock()
        # The running command's calls end by then (None: each waits `call_timeout`).
        self._deadline: Deadline | None = None
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
        value = self._read_after_a_timeout(lambda: self._get(node, name))
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
            state = self._read_after_a_timeout(lambda: self._get_state(node))
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

    def _read_after_a_timeout(self, read: Callable[[], T]) -> T:
        """`read()` of a node that did not answer in time: it may still be busy with that
        request, so a read that times out, or finds it in a transition, is asked again
        for up to PATIENCE_AFTER_A_TIMEOUT call timeouts."""
        give_up = time.monotonic() + PATIENCE_AFTER_A_TIMEOUT * self.call_timeout
        while True:
            try:
                return read()
            except (CallTimedOut, InTransition) as error:
                if time.monotonic() >= give_up:
                    raise
                if isinstance(error, InTransition):
                    time.sleep(_POLL)

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

    # -- service calls ------------------------------------------------------------------

    def _client(self, node: str, kind: str, service_type: Any) -> Any:
        with self._lock:
            client = self._clients.get((node, kind))
            if client is None:
                client = self.node.create_client(service_type, f"{node}/{kind}")
                self._clients[(node, kind)] = client
        return client

    def _call(self, node: str, kind: str, service_type: Any, request: Any, what: str) -> Any:
        client = self._client(node, kind, service_type)
        limit, why = self._time_left()
        if limit <= 0:
            raise BindingError(f"node {node}: {what} not asked: no time left ({why})")
        wait = min(limit, max(SERVICE_WAIT, self.discovered_by - time.monotonic()))
        if not client.wait_for_service(timeout_sec=wait):
            raise BindingError(f"node {node} does not answer on {node}/{kind} ({what})")
        limit, why = self._time_left()
        future = client.call_async(request)
        finished = threading.Event()
        future.add_done_callback(lambda _: finished.set())
        if not finished.wait(max(limit, 0.0)):
            client.remove_pending_request(future)
            within = f"{limit:.3g} s ({why})" if why else f"{limit:g} s"
            raise CallTimedOut(f"node {node} did not answer {what} within {within}")
        response = future.result()
        if response is None:
            raise BindingError(f"node {node}: {what} failed ({future.exception()})")
        return response

    def _time_left(self) -> tuple[float, str]:
        """How long the next call may wait for its answer, and why not `call_timeout`
        ("" when it is): the command's deadline comes first."""
        deadline = self._deadline
        if deadline is not None:
            left = deadline.at - time.monotonic()
            if left < self.call_timeout:
                return left, deadline.why
        return self.call_timeout, ""

    def _get(self, node: str, name: str) -> Any:
        response = self._call(
            node,
            "get_parameters",
            GetParameters,
            GetParameters.Request(names=[name]),
            f"reading parameter {name}",
        )
        values = list(response.values)
        return values[0] if len(values) == 1 else ParameterValue()

    def _set(self, node: str, name: str, value: Any, layer: str = "") -> None:
        request = SetParameters.Request(parameters=[Parameter(name=name, value=value)])
        what = f"setting parameter {name} to {shown(value)}"
        response = self._call(node, "set_parameters", SetParameters, request, what)
        results = list(response.results)
        if len(results) != 1 or not results[0].successful:
            reason = _printable(results[0].reason) if results else "no result"
            by = f" (for layer {layer})" if layer else ""
            raise BindingError(
                f"node {node} rejected parameter {name} = {shown(value)}{by}: "
                f"{reason or 'no reason given'}"
            )

    def _get_state(self, node: str) -> str:
        response = self._call(
            node, "get_state", GetState, GetState.Request(), "its lifecycle state"
        )
        state = PRIMARY_STATES.get(response.current_state.id)
        if state is None:
            label = _printable(response.current_state.label)
            raise InTransition(f"lifecycle node {node} is in transition state {label!r}")
        return state

    def _change_state(
        self, node: str, transition_id: int, label: str, layer: str = "", current: str = ""
    ) -> None:
        request = ChangeState.Request(transition=Transition(id=transition_id, label=label))
        response = self._call(node, "change_state", ChangeState, request, f"transition {label}")
        if not response.success:
            by = f" (for layer {layer})" if layer else ""
            state = f" from {current}" if current else ""
            raise BindingError(f"lifecycle node {node}: transition {label}{state} failed{by}")


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
