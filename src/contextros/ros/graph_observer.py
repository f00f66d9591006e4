"""The manager's one view of the ROS graph's state: lifecycle states and parameters, read
from the nodes themselves. The rules' graph conditions (`contextros.ros.rules`), the
bindings' actual state (`contextros.ros.binding_watch`) and `contextros record` consume it.

Trust: any process may publish on `/parameter_events` and on a node's `transition_event`,
so an event is a hint and nothing more: the observer reads the node it names
(`get_parameters` for the parameters followed, `get_state`) and hands on the node's answer.
What an event says of a value is never used.

`GraphObserver` holds one subscription per topic (`/parameter_events`, each followed
lifecycle node's `NODE/transition_event`) and one reader per node and service (`_Reader`):

- a node is read when it appears on the graph (a restart too: a lifecycle node announces no
  transition then; seen as new event publishers), once its events reach the observer (a change
  between the answer and the first event heard would be lost), then after each event;
- an event that comes while a request is out makes the answer suspect (it may be older than
  the change): it is dropped and the node asked again (MAX_DROPPED times in a row at most:
  then it is taken and the node read again, so a flood of events cannot hold values back);
- a request unanswered after REQUEST_TIMEOUT is sent again; a node that leaves the graph is
  handed on as absent (`NodeRead.absent`).

A read is handed on as the message an event would have been, on the channel `NODE/get_state`
(a TransitionEvent to the current state; to `unknown` when absent) or `NODE/get_parameters`
(a ParameterEvent with the values as new parameters; deleting them when absent), stamped with
the time of the read: `contextros.rules.graph` reads these, and `contextros record` writes
them, so the replay reads what the manager read.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from builtin_interfaces.msg import Time
from lifecycle_msgs.msg import State, TransitionEvent
from lifecycle_msgs.srv import GetState
from rcl_interfaces.msg import Parameter, ParameterEvent
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_parameter_events

from contextros.bindings.values import UNKNOWN_STATE
from contextros.rules.graph import GET_PARAMETERS, GET_STATE, PARAMETER_EVENTS, TRANSITION_EVENT

# A lifecycle node's transition events (rcl_lifecycle publishes them reliable, depth 10).
TRANSITION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE
)
# Seconds a node may be on the graph without the service followed before that is logged
# (a node that is not a lifecycle node, say): its services appear with it.
SERVICE_GRACE = 3.0
# Seconds before an unanswered request is sent again (an answer lost, a node restarting).
REQUEST_TIMEOUT = 2.0
# Answers dropped in a row because events kept coming meanwhile, at most: then one is taken
# (and the node read again), so a flood of events, forged or not, cannot hold a value back.
MAX_DROPPED = 3
# What one event is looked at for at most (anyone can publish one).
MAX_NODE_NAME = 256
MAX_PARAMETERS_PER_EVENT = 64


@dataclass(frozen=True)
class NodeRead:
    """What `node` answered (or that it is absent) on `channel`, as `message`. `asked`
    (monotonic) when the request went out; `noticed` (wall clock) when the change was first
    noticed: the first event since the last read, else the request."""

    channel: str
    node: str
    message: Any
    asked: float
    noticed: float
    absent: bool = False

    @property
    def state(self) -> bool:
        """A lifecycle state (get_state), not parameters."""
        return self.channel.endswith(f"/{GET_STATE}")


class _Reader:
    """One service of one node: whether it is to be read, and the request out."""

    def __init__(self, fqn: str, channel: str, client: Any, events: str) -> None:
        self.fqn = fqn
        self.channel = channel
        self.client = client
        self.events = events  # the topic of the node's events
        self.names: list[str] = []  # the parameters read (get_parameters)
        self.wanted = True  # to be read (at first, after an event, a restart, a refresh)
        self.noticed: float | None = None  # wall clock of the first event since the last read
        self.pending: Any = None  # the request's future
        self.sent = 0.0
        self.stale = False  # an event came while the request was out: ask again
        self.dropped = 0  # answers dropped in a row for that
        self.logged_missing = False


class GraphObserver:
    """Reads the lifecycle states and parameters `follow`ed on `node`'s graph and hands each
    read to every `subscribe`d callback (module docstring). `listening(topic)` says whether
    the caller hears the node's events yet (default: this observer's own subscription)."""

    def __init__(
        self,
        node: Node,
        *,
        period: float = 0.2,
        listening: Callable[[str], bool] | None = None,
    ) -> None:
        self.node = node
        self._listening = listening
        self._callbacks: list[Callable[[NodeRead], None]] = []
        self._readers: dict[str, _Reader] = {}  # channel -> reader
        self._subscriptions: dict[str, Any] = {}  # topic -> subscription
        self._present: set[str] = set()
        self._since: dict[str, float] = {}  # node -> when it appeared (monotonic)
        # Reader's channel -> its node's publishers of events (gids) at the last poll.
        self._publishers: dict[str, set[bytes]] = {}
        self._timer = node.create_timer(period, self.poll)

    # -- what to follow, and who hears --------------------------------------------------

    def follow(
        self, lifecycle: Iterable[str] = (), parameters: Mapping[str, Iterable[str]] | None = None
    ) -> None:
        """Read these nodes' lifecycle states and these parameters (resolved node -> names),
        besides what is followed already."""
        for fqn in lifecycle:
            topic = f"{fqn}/{TRANSITION_EVENT}"
            if topic not in self._subscriptions:
                self._subscriptions[topic] = self.node.create_subscription(
                    TransitionEvent, topic, lambda _, n=fqn: self._transition(n), TRANSITION_QOS
                )
            self._reader(fqn, GET_STATE, GetState, topic)
        for fqn, names in (parameters or {}).items():
            if PARAMETER_EVENTS not in self._subscriptions:
                self._subscriptions[PARAMETER_EVENTS] = self.node.create_subscription(
                    ParameterEvent,
                    PARAMETER_EVENTS,
                    self._parameter_event,
                    qos_profile_parameter_events,
                )
            reader = self._reader(fqn, GET_PARAMETERS, GetParameters, PARAMETER_EVENTS)
            added = [name for name in names if name not in reader.names]
            if added:
                reader.names += added
                reader.wanted = True
        self.poll()

    def subscribe(self, callback: Callable[[NodeRead], None]) -> None:
        self._callbacks.append(callback)

    def refresh(self, fqn: str) -> None:
        """Read `fqn` again (a consumer doubts what it has: a read out while it changed it)."""
        for reader in self._readers.values():
            if reader.fqn == fqn:
                self._hint(reader)

    def _reader(self, fqn: str, service: str, service_type: Any, events: str) -> _Reader:
        channel = f"{fqn}/{service}"
        reader = self._readers.get(channel)
        if reader is None:
            client: Any = self.node.create_client(service_type, channel)
            reader = self._readers[channel] = _Reader(fqn, channel, client, events)
        reader.wanted = True  # (a new follower has no value yet)
        return reader

    # -- events: hints ------------------------------------------------------------------

    def _parameter_event(self, event: Any) -> None:
        fqn = event.node
        if not isinstance(fqn, str) or len(fqn) > MAX_NODE_NAME:
            return
        reader = self._readers.get(f"{fqn}/{GET_PARAMETERS}")
        if reader is None:
            return
        named = [
            parameter.name
            for kind in (event.new_parameters, event.changed_parameters, event.deleted_parameters)
            for parameter in kind[:MAX_PARAMETERS_PER_EVENT]
        ]
        if any(name in reader.names for name in named):
            self._hint(reader)

    def _transition(self, fqn: str) -> None:
        reader = self._readers.get(f"{fqn}/{GET_STATE}")
        if reader is not None:
            self._hint(reader)

    def _hint(self, reader: _Reader) -> None:
        if reader.noticed is None:
            reader.noticed = time.time()
        if reader.pending is not None:
            reader.stale = True
            return
        reader.wanted = True
        if reader.fqn in self._present and reader.client.service_is_ready():
            self._ask(reader, time.monotonic())

    # -- the graph ----------------------------------------------------------------------

    def poll(self) -> None:
        present = {
            f"{namespace.rstrip('/')}/{name}"
            for name, namespace in self.node.get_node_names_and_namespaces()
        }
        now = time.monotonic()
        publishers = self._event_publishers()
        for reader in self._readers.values():
            if reader.fqn not in present:
                if reader.fqn in self._present:
                    self._absent(reader, now)
                continue
            self._since.setdefault(reader.fqn, now)
            gids = publishers.get((reader.events, reader.fqn), set())
            if gids - self._publishers.get(reader.channel, set()):
                reader.wanted = True  # new event publishers: it (re)started
            self._publishers[reader.channel] = gids
            if not reader.wanted:
                continue
            if reader.pending is not None and now - reader.sent < REQUEST_TIMEOUT:
                continue
            if not reader.client.service_is_ready():
                self._missing(reader, now)
                continue
            if gids and self._hears(reader.events):
                self._ask(reader, now)
        for fqn in self._present - present:
            self._since.pop(fqn, None)
        self._present = {reader.fqn for reader in self._readers.values() if reader.fqn in present}

    def _event_publishers(self) -> dict[tuple[str, str], set[bytes]]:
        """(events topic, node) -> the gids of the node's publishers on it."""
        found: dict[tuple[str, str], set[bytes]] = {}
        for topic in {reader.events for reader in self._readers.values()}:
            for info in self.node.get_publishers_info_by_topic(topic):
                fqn = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                found.setdefault((topic, fqn), set()).add(bytes(info.endpoint_gid))
        return found

    def _hears(self, topic: str) -> bool:
        if self._listening is not None:
            return self._listening(topic)
        subscription = self._subscriptions.get(topic)
        return subscription is not None and subscription.get_publisher_count() > 0

    # -- reads --------------------------------------------------------------------------

    def _ask(self, reader: _Reader, now: float) -> None:
        if reader.channel.endswith(f"/{GET_STATE}"):
            request: Any = GetState.Request()
        else:
            request = GetParameters.Request(names=list(reader.names))
        if reader.pending is not None:  # unanswered: forgotten
            reader.client.remove_pending_request(reader.pending)
        reader.sent, reader.stale, reader.wanted = now, False, False
        future = reader.client.call_async(request)
        reader.pending = future
        future.add_done_callback(lambda done, r=reader, s=now: self._answered(r, done, s))

    def _answered(self, reader: _Reader, future: Any, asked: float) -> None:
        if reader.pending is not future:
            return  # superseded (sent again, or the node left)
        reader.pending = None
        if future.cancelled() or future.exception() is not None:
            reader.wanted = True  # (asked again at the next poll)
            return
        if reader.stale and reader.dropped < MAX_DROPPED:
            reader.dropped += 1
            reader.wanted = True
            if reader.fqn in self._present and reader.client.service_is_ready():
                self._ask(reader, time.monotonic())
            return
        if reader.stale:  # (events keep coming: this answer, then another read)
            reader.wanted = True
        reader.dropped = 0
        response = future.result()
        wall = time.time()
        if reader.channel.endswith(f"/{GET_STATE}"):
            message: Any = TransitionEvent(goal_state=response.current_state, timestamp=_ns(wall))
        else:
            if len(response.values) != len(reader.names):
                self.node.get_logger().error(
                    f"{reader.fqn} answered get_parameters with {len(response.values)} values "
                    f"for {len(reader.names)} names: ignored"
                )
                return
            message = ParameterEvent(
                stamp=_stamp(wall),
                node=reader.fqn,
                new_parameters=[
                    Parameter(name=name, value=value)
                    for name, value in zip(reader.names, response.values, strict=True)
                ],
            )
        noticed = reader.noticed if reader.noticed is not None else wall
        reader.noticed = None
        self._deliver(NodeRead(reader.channel, reader.fqn, message, asked, noticed))
        if reader.wanted and reader.client.service_is_ready():
            self._ask(reader, time.monotonic())

    def _absent(self, reader: _Reader, now: float) -> None:
        if reader.pending is not None:
            reader.client.remove_pending_request(reader.pending)
        reader.pending, reader.logged_missing, reader.wanted = None, False, True
        self._publishers.pop(reader.channel, None)
        wall = time.time()
        if reader.channel.endswith(f"/{GET_STATE}"):
            message: Any = TransitionEvent(goal_state=State(id=UNKNOWN_STATE), timestamp=_ns(wall))
        else:
            message = ParameterEvent(
                stamp=_stamp(wall),
                node=reader.fqn,
                deleted_parameters=[Parameter(name=name) for name in reader.names],
            )
        self._deliver(NodeRead(reader.channel, reader.fqn, message, now, wall, absent=True))

    def _deliver(self, read: NodeRead) -> None:
        for callback in self._callbacks:
            callback(read)

    def _missing(self, reader: _Reader, now: float) -> None:
        if reader.logged_missing or now - self._since.get(reader.fqn, now) < SERVICE_GRACE:
            return
        reader.logged_missing = True
        kind = "lifecycle node" if reader.channel.endswith(GET_STATE) else "node with parameters"
        self.node.get_logger().warning(
            f"{reader.fqn} is on the graph but has no {reader.channel} service (is it a "
            f"{kind}?): its state is not read until it has"
        )

    def destroy(self) -> None:
        self._timer.cancel()
        for reader in self._readers.values():
            self.node.destroy_client(reader.client)
        for subscription in self._subscriptions.values():
            self.node.destroy_subscription(subscription)


def _ns(wall: float) -> int:
    return int(wall * 1e9)


def _stamp(wall: float) -> Any:
    nanoseconds = _ns(wall)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)
