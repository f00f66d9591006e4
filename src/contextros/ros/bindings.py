"""Layers that drive ROS, carried out by the Layer manager over standard ROS services.

`parameter` declarations go through `/<node>/get_parameters` and `/<node>/set_parameters`
(rcl_interfaces), `lifecycle` declarations through `/<node>/get_state` and
`/<node>/change_state` (lifecycle_msgs): every ROS 2 node has the former, every managed node
the latter, so the nodes need to know nothing of ContextROS and may be C++.

A switch runs in a worker thread (blocking on the answers while the manager's executor
keeps spinning and delivers them), and either completes or is rolled back: a parameter a
node rejects, a node that does not answer, or a failed lifecycle transition undoes what the
switch already did, in reverse order, and names node, parameter or transition and the reason.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
    from_json,
    parameter_fields,
    plain_value,
    shown_parameter,
    to_json,
)
from contextros.language.bindings import LifecycleBinding, ParameterBinding
from contextros.language.bindings import ParameterValue as Value
from contextros.ros.messages import seconds_to_stamp

_MAX_REASON = 300


class BindingError(Exception):
    """A switch's ROS side could not be done (already rolled back); the message says why."""


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
        call_timeout: float = 2.0,
        discovery_time: float = 5.0,
        memory: Path | None = None,
    ) -> None:
        self.node = node
        self.bindings = bindings
        self.call_timeout = call_timeout
        # Until this (monotonic) time, a node's services may still be being discovered: a
        # call waits for them until then, not just `call_timeout`.
        self.discovered_by = time.monotonic() + discovery_time
        # The configuration ROS reflects now (what the last completed switch was for).
        self.applied: tuple[str, ...] = ()
        # Values and states from before any layer touched them, to restore.
        self._original_parameters: dict[tuple[str, str], Any] = {}
        self._original_states: dict[str, str] = {}
        self._clients: dict[tuple[str, str], Any] = {}
        # (node, parameter or "" for lifecycle) -> the last result of applying it.
        self._results: dict[tuple[str, str], BindingResult] = {}
        # What the switches read and set on the nodes, for the actual state (`take_readings`).
        self._readings: list[tuple[BindingKey, Reading]] = []
        self._lock = threading.Lock()
        # Where `applied` and the originals are kept across restarts (next to the state file).
        self.memory = memory
        if memory is not None:
            self._load(memory)
        # Discovery of a service takes a while (seconds on a loaded machine): the clients
        # exist from the start, so the first switch does not wait for it.
        for name in sorted({self.resolve(b.node) for b in bindings.parameters}):
            self._client(name, "get_parameters", GetParameters)
            self._client(name, "set_parameters", SetParameters)
        for name in sorted({self.resolve(b.node) for b in bindings.lifecycles}):
            self._client(name, "get_state", GetState)
            self._client(name, "change_state", ChangeState)

    # -- memory across restarts ---------------------------------------------------------

    def _load(self, path: Path) -> None:
        """Take `applied` and the originals from `path`; a damaged file is logged and
        ignored (the values in place are then taken for the originals, as without one)."""
        try:
            if not path.exists():
                return
            data = json.loads(path.read_text(encoding="utf-8"))
            applied = tuple(data["applied"])
            parameters = {
                (str(p["node"]), str(p["name"])): _value_from_json(p) for p in data["parameters"]
            }
            states = {str(node): str(state) for node, state in data["lifecycles"].items()}
            if not all(isinstance(name, str) for name in applied) or not all(
                state in PRIMARY_STATES.values() for state in states.values()
            ):
                raise ValueError("unexpected layer names or lifecycle states")
        except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
            self.node.get_logger().error(
                f"ignored {path} (values to restore from before the last restart): {error!r}"
            )
            return
        self.applied = applied
        self._original_parameters = parameters
        self._original_states = states

    def _save(self) -> None:
        if self.memory is None:
            return
        parameters = [
            {"node": node, "name": name, **_value_to_json(value)}
            for (node, name), value in sorted(self._original_parameters.items())
        ]
        text = json.dumps(
            {
                "applied": list(self.applied),
                "parameters": parameters,
                "lifecycles": dict(sorted(self._original_states.items())),
            },
            indent=2,
        )
        partial = self.memory.with_name(f".{self.memory.name}.{os.getpid()}.tmp")
        try:
            self.memory.parent.mkdir(parents=True, exist_ok=True)
            with partial.open("w", encoding="utf-8") as stream:
                stream.write(text)
                stream.flush()
                os.fsync(stream.fileno())
            partial.replace(self.memory)
        except OSError as error:
            self.node.get_logger().error(f"{self.memory} not written: {error}")

    # -- names --------------------------------------------------------------------------

    def resolve(self, name: str) -> str:
        """A declared node name, fully qualified: relative names in the manager's namespace."""
        if name.startswith("/"):
            return name
        namespace = self.node.get_namespace().rstrip("/")
        return f"{namespace}/{name.removeprefix('~/')}"

    def plan(self, old: Sequence[str], new: Sequence[str]) -> Plan:
        return self.bindings.plan(old, new, self.resolve)

    # -- the switch (worker thread) -----------------------------------------------------

    def switch(self, old: Sequence[str], new: Sequence[str]) -> None:
        """Make ROS reflect `new` (coming from `old`); BindingError, rolled back, if not."""
        plan = self.plan(old, new)
        undo: list[tuple[str, Any]] = []
        # The originals are forgotten only once the whole switch succeeded: a restore that
        # fails, or one a later step rolls back, must find them again next time.
        originals = _Originals()
        try:
            for change in plan.parameters:
                self._parameter(change, undo, originals)
            for lifecycle in plan.lifecycles:
                self._lifecycle(lifecycle, undo, originals)
        except BindingError:
            if self._roll_back(undo):
                # Everything is as before: what this switch read first is read again.
                self._forget(originals.read)
            self._save()
            raise
        self._forget(originals.restored)
        self.applied = tuple(new)
        self._save()

    def _forget(self, keys: list[tuple[str, Any]]) -> None:
        for kind, key in keys:
            if kind == "parameter":
                self._original_parameters.pop(key, None)
            else:
                self._original_states.pop(key, None)

    def _roll_back(self, undo: list[tuple[str, Any]]) -> bool:
        """Undo `undo` in reverse order; False if a step failed (logged)."""
        complete = True
        for kind, step in reversed(undo):
            try:
                if kind == "parameter":
                    node, name, previous = step
                    self._set(node, name, previous)
                    self._seen((node, name), previous)
                else:
                    node, path = step
                    for transition_id, label in path:
                        self._change_state(node, transition_id, label)
                    self._seen((node, ""), self._get_state(node))
            except BindingError as error:
                complete = False
                self.node.get_logger().error(f"rolling back: {error}")
        return complete

    def _parameter(
        self, change: ParameterChange, undo: list[tuple[str, Any]], originals: _Originals
    ) -> None:
        key = change.key
        current = self._get(change.node, change.name)
        self._seen(key, current)
        if key not in self._original_parameters:
            self._original_parameters[key] = current
            originals.read.append(("parameter", key))
        if change.restore:
            target = self._original_parameters[key]
            originals.restored.append(("parameter", key))
            if target.type == NOT_SET:
                return  # it had no value before: leave the last one
        else:
            target = to_parameter_value(change.value, like=current)
        with self._outcome((change.node, change.name), change, shown(target)):
            self._set(change.node, change.name, target, change.layer)
        self._seen(key, target)
        undo.append(("parameter", (change.node, change.name, current)))

    def _lifecycle(
        self, change: LifecycleChange, undo: list[tuple[str, Any]], originals: _Originals
    ) -> None:
        current = self._get_state(change.node)
        self._seen((change.node, ""), current)
        if change.node not in self._original_states:
            self._original_states[change.node] = current
            originals.read.append(("lifecycle", change.node))
        if change.restore:
            wanted: str | None = self._original_states[change.node]
            originals.restored.append(("lifecycle", change.node))
        else:
            wanted = change.state
        assert wanted is not None
        try:
            path = transitions(current, wanted)
        except ValueError as error:
            raise BindingError(f"lifecycle node {change.node}: {error}") from None
        done: list[tuple[int, str]] = []
        with self._outcome((change.node, ""), change, wanted):
            for transition_id, label in path:
                try:
                    self._change_state(change.node, transition_id, label, change.layer, current)
                except BindingError:
                    if done:
                        undo.append(("lifecycle", (change.node, _reverse(done))))
                    raise
                done.append((transition_id, label))
        self._seen((change.node, ""), wanted)
        if done:
            undo.append(("lifecycle", (change.node, _reverse(done))))

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
        wait = max(self.call_timeout, self.discovered_by - time.monotonic())
        if not client.wait_for_service(timeout_sec=wait):
            raise BindingError(f"node {node} does not answer on {node}/{kind} ({what})")
        future = client.call_async(request)
        finished = threading.Event()
        future.add_done_callback(lambda _: finished.set())
        if not finished.wait(self.call_timeout):
            client.remove_pending_request(future)
            raise BindingError(f"node {node} did not answer {what} within {self.call_timeout:g} s")
        response = future.result()
        if response is None:
            raise BindingError(f"node {node}: {what} failed ({future.exception()})")
        return response

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
            raise BindingError(f"lifecycle node {node} is in transition state {label!r}")
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


def _value_to_json(message: Any) -> dict[str, Any]:
    """Kept across restarts: the types a layer can set (another is kept as not set: a
    restarted manager reads the value in place instead)."""
    return to_json(message)


def _value_from_json(data: Any) -> Any:
    kind, field_name, value = from_json(data)
    message = ParameterValue(type=kind)
    if field_name:
        setattr(message, field_name, value)
    return message


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
