"""Calls to ROS nodes' standard parameter and lifecycle services for the binding driver,
each with a bounded wait, and what a call that fails or is not answered in time means.

A call waits up to `call_timeout` for its answer, and no longer than the running command's
`Deadline`; a request that goes out and gets no answer in time raises `CallTimedOut`: the
node may have carried it out, so the caller must find out (`read_after_a_timeout`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.msg import Parameter, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node

from contextros.bindings.values import NOT_SET, PRIMARY_STATES, parameter_fields, shown_parameter
from contextros.language.bindings import ParameterValue as Value

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


class NodeCalls:
    """The service clients of the bound nodes and the calls the binding driver makes."""

    def __init__(self, node: Node, call_timeout: float, discovery_time: float) -> None:
        self.node = node
        self.call_timeout = call_timeout
        # Until this (monotonic) time, a node's services may still be being discovered: a
        # call waits for them until then, not just `SERVICE_WAIT`.
        self.discovered_by = time.monotonic() + discovery_time
        self._clients: dict[tuple[str, str], Any] = {}
        self._lock = threading.Lock()
        # The running command's calls end by then (None: each waits `call_timeout`).
        self._deadline: Deadline | None = None

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

    def read_after_a_timeout(self, read: Callable[[], T]) -> T:
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
