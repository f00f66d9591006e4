"""What the rules' graph conditions need besides topics: a node's state when it appears.

Events tell changes only (`/parameter_events`, `NODE/transition_event`), so a rule would be
right only after the first change. `GraphWatch` follows the ROS graph for the nodes the
rules read: when one appears it asks the node's `get_state` / `get_parameters` service, and
hands the answer on as the message an event would have been (a TransitionEvent to the
current state; a ParameterEvent with the values as new parameters) on the channel
`NODE/get_state` / `NODE/get_parameters`; when the node leaves the graph it hands on that it
has no values (a TransitionEvent to `unknown`, a ParameterEvent deleting them). The manager
reads them with `contextros.rules.graph.GraphInputs`; `contextros record` writes them, so the
replay reads the same (contextros.rules.graph says why).

A node is asked only once its event publisher is on the graph (and the caller listens to
that topic, `listening`): a change between the answer and the first event heard would be
lost. An answer to a request sent before an event of the node (`event_seen`) may be older
than that event: it is dropped and the node asked again.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from lifecycle_msgs.msg import State, TransitionEvent
from lifecycle_msgs.srv import GetState
from rcl_interfaces.msg import Parameter, ParameterEvent
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node

from contextros.rules.graph import (
    GET_PARAMETERS,
    GET_STATE,
    PARAMETER_EVENTS,
    TRANSITION_EVENT,
)

# Seconds a node may be on the graph without the service the rules need before that is
# logged (a node that is not a lifecycle node, say): its services appear with it.
SERVICE_GRACE = 3.0
# Seconds before an unanswered request is sent again (an answer lost, a node restarting).
REQUEST_TIMEOUT = 2.0

Deliver = Callable[[str, Any], None]  # (channel, message)


class _Fetch:
    """One service of one node: asked once the node is on the graph, again if it returns."""

    def __init__(self, node: Node, fqn: str, channel: str, client: Any, events: str) -> None:
        self.node = node
        self.fqn = fqn
        self.channel = channel
        self.client = client
        self.events = events  # the topic of the node's events
        self.done = False  # answered since the node appeared
        self.pending: Any = None  # the request's future
        self.sent = 0.0
        self.stale = False  # an event came while the request was out: ask again
        self.logged_missing = False


class GraphWatch:
    """Follows `lifecycle_nodes` and `parameters` (resolved node -> names) on `node`'s graph
    and hands their current values, and their absence, to `deliver` (module docstring)."""

    def __init__(
        self,
        node: Node,
        lifecycle_nodes: Sequence[str],
        parameters: Mapping[str, Sequence[str]],
        deliver: Deliver,
        *,
        period: float = 0.2,
        listening: Callable[[str], bool] = lambda topic: True,
    ) -> None:
        self.node = node
        self._deliver = deliver
        self._listening = listening
        self._parameters = {fqn: list(names) for fqn, names in parameters.items()}
        self._fetches: list[_Fetch] = []
        for fqn in lifecycle_nodes:
            client: Any = node.create_client(GetState, f"{fqn}/get_state")
            events = f"{fqn}/{TRANSITION_EVENT}"
            self._fetches.append(_Fetch(node, fqn, f"{fqn}/{GET_STATE}", client, events))
        for fqn in self._parameters:
            client = node.create_client(GetParameters, f"{fqn}/get_parameters")
            channel = f"{fqn}/{GET_PARAMETERS}"
            self._fetches.append(_Fetch(node, fqn, channel, client, PARAMETER_EVENTS))
        self._present: set[str] = set()
        self._since: dict[str, float] = {}  # node -> when it appeared
        self._timer = node.create_timer(period, self.poll)
        self.poll()

    def event_seen(self, fqn: str) -> None:
        """An event of `fqn` came: an answer to a request sent before it may be older."""
        for fetch in self._fetches:
            if fetch.fqn == fqn and fetch.pending is not None:
                fetch.stale = True

    def poll(self) -> None:
        present = {
            f"{namespace.rstrip('/')}/{name}"
            for name, namespace in self.node.get_node_names_and_namespaces()
        }
        now = time.monotonic()
        for fetch in self._fetches:
            if fetch.fqn not in present:
                if fetch.fqn in self._present:
                    self._absent(fetch)
                continue
            self._since.setdefault(fetch.fqn, now)
            if fetch.done:
                continue
            if fetch.pending is not None and now - fetch.sent < REQUEST_TIMEOUT:
                continue
            if not fetch.client.service_is_ready():
                self._missing(fetch, now)
                continue
            if self._events_heard(fetch):
                self._ask(fetch, now)
        for fqn in self._present - present:
            self._since.pop(fqn, None)
        self._present = {fetch.fqn for fetch in self._fetches if fetch.fqn in present}

    def _events_heard(self, fetch: _Fetch) -> bool:
        """Whether the node's events reach this node yet (module docstring)."""
        publishers = self.node.get_publishers_info_by_topic(fetch.events)
        found = any(
            f"{info.node_namespace.rstrip('/')}/{info.node_name}" == fetch.fqn
            for info in publishers
        )
        return found and self._listening(fetch.events)

    def _ask(self, fetch: _Fetch, now: float) -> None:
        if fetch.channel.endswith(GET_STATE):
            request: Any = GetState.Request()
        else:
            request = GetParameters.Request(names=self._parameters[fetch.fqn])
        fetch.sent, fetch.stale = now, False
        future = fetch.client.call_async(request)
        fetch.pending = future
        future.add_done_callback(lambda done, f=fetch: self._answered(f, done))

    def _answered(self, fetch: _Fetch, future: Any) -> None:
        if fetch.pending is not future:
            return  # superseded (sent again, or the node left)
        fetch.pending = None
        if fetch.stale or future.cancelled() or future.exception() is not None:
            return  # asked again at the next poll
        response = future.result()
        if fetch.channel.endswith(GET_STATE):
            message: Any = TransitionEvent(goal_state=response.current_state)
        else:
            names = self._parameters[fetch.fqn]
            if len(response.values) != len(names):
                self.node.get_logger().error(
                    f"{fetch.fqn} answered get_parameters with {len(response.values)} values "
                    f"for {len(names)} names: ignored"
                )
                return
            message = ParameterEvent(
                node=fetch.fqn,
                new_parameters=[
                    Parameter(name=name, value=value)
                    for name, value in zip(names, response.values, strict=True)
                ],
            )
        fetch.done = True
        self._deliver(fetch.channel, message)

    def _absent(self, fetch: _Fetch) -> None:
        fetch.done, fetch.pending, fetch.logged_missing = False, None, False
        if fetch.channel.endswith(GET_STATE):
            message: Any = TransitionEvent(goal_state=State(id=State.PRIMARY_STATE_UNKNOWN))
        else:
            names = self._parameters[fetch.fqn]
            message = ParameterEvent(
                node=fetch.fqn, deleted_parameters=[Parameter(name=name) for name in names]
            )
        self._deliver(fetch.channel, message)

    def _missing(self, fetch: _Fetch, now: float) -> None:
        if fetch.logged_missing or now - self._since.get(fetch.fqn, now) < SERVICE_GRACE:
            return
        fetch.logged_missing = True
        service = fetch.client.srv_name
        kind = "lifecycle node" if fetch.channel.endswith(GET_STATE) else "node with parameters"
        self.node.get_logger().warning(
            f"rules on {fetch.fqn} wait: the node is on the graph but has no {service} "
            f"service (is it a {kind}?)"
        )

    def destroy(self) -> None:
        self._timer.cancel()
        for fetch in self._fetches:
            self.node.destroy_client(fetch.client)
