"""`contextros record`: the protocol's topics and the rules' input topics into MCAP.

For rules on the ROS graph's state (`lifecycle NODE`, `param NODE.PARAMETER`) that is
`/parameter_events` and each lifecycle node's `transition_event` topic (as they came: hints,
anyone may publish them), plus what the nodes answered when the recorder read them as the
manager does (`GraphObserver`: when they appear, after each of their events) and that they
left, written as stamped events on the channels `NODE/get_state` / `NODE/get_parameters`,
so the replay has the values the manager had (contextros.rules.graph).

Each topic is subscribed once the ROS graph shows its type, raw (the serialized CDR bytes
are written as they arrived, as rosbag2 does), with its message definition as a `ros2msg`
schema, so `ros2 bag`, Foxglove and `contextros rules replay` read the file. Log times are
the recorder's receive times (wall clock, nanoseconds), as in rosbag2. The file is written
by `RecordingWriter`: killed without warning, the recorder loses at most the messages of
its last CHUNK_PERIOD (and `contextros repair` makes the file whole again).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any, BinaryIO

from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_parameter_events
from rclpy.serialization import serialize_message

from contextros.language.rules import RuleDecl
from contextros.recording.definitions import DefinitionError, message_definition, type_of
from contextros.recording.writer import CHUNK_PERIOD, RecordingWriter
from contextros.ros.graph_observer import TRANSITION_QOS, GraphObserver, NodeRead
from contextros.ros.message_types import message_class
from contextros.ros.rules import RULE_QOS
from contextros.ros.topics import (
    HEARTBEAT_QOS,
    HEARTBEAT_TOPIC,
    PROPOSAL_QOS,
    PROPOSAL_TOPIC,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)
from contextros.rules.graph import PARAMETER_EVENTS, GraphInputs, graph_topics


def _deep(qos: QoSProfile) -> QoSProfile:
    """`qos` with a reader history deep enough that a recorder that falls behind (a loaded
    machine) loses no sample: the state topic keeps only the last one, and two states a
    few ms apart would otherwise leave one in the recording."""
    return QoSProfile(
        history=qos.history,
        depth=max(qos.depth, 1000),
        reliability=qos.reliability,
        durability=qos.durability,
    )


PROTOCOL_TOPICS: dict[str, QoSProfile] = {
    STATE_TOPIC: _deep(STATE_QOS),  # transient local: the current state arrives at once
    HEARTBEAT_TOPIC: _deep(HEARTBEAT_QOS),
    STATUS_TOPIC: _deep(STATUS_QOS),
    PROPOSAL_TOPIC: _deep(PROPOSAL_QOS),
}


def rule_topics(rules: Sequence[RuleDecl]) -> dict[str, QoSProfile]:
    """The topics `rules` read, named as they name them (`~/x` is the manager's, not the
    recorder's: the caller resolves it), with the QoS to record each with."""
    topics = {ref.topic: RULE_QOS for rule in rules for ref in rule.fields}
    for topic in graph_topics(rules):
        topics[topic] = (
            qos_profile_parameter_events if topic == PARAMETER_EVENTS else TRANSITION_QOS
        )
    return topics


class Recorder:
    """Records `topics` (names relative to `node`'s namespace, or absolute) into `output`,
    and what the nodes `graph_rules` read the state of answered (module docstring)."""

    def __init__(
        self,
        node: Node,
        output: Path,
        topics: dict[str, QoSProfile],
        *,
        discovery_period: float = 0.1,
        graph_rules: Sequence[RuleDecl] = (),
    ) -> None:
        self.node = node
        self.output = output
        self._unbound = {_resolved(node, t): qos for t, qos in topics.items()}
        self._stream: BinaryIO = output.open("wb")
        self._writer = RecordingWriter(self._stream)
        self._schemas: dict[str, int] = {}
        self._refused: dict[str, str] = {}  # topic -> the type it was refused with
        self._subscriptions: list[Any] = []
        self._by_topic: dict[str, Any] = {}  # resolved topic -> its subscription
        self.counts: Counter[str] = Counter()
        self._sequence = 0
        self._finished = False
        self._discovery = node.create_timer(discovery_period, self._discover)
        self._chunks = node.create_timer(CHUNK_PERIOD, self._close_chunk)
        self._discover()
        self._fetched: dict[str, int] = {}  # channel name -> id, of the answers written
        graph = GraphInputs(graph_rules, lambda name: _resolved(node, name))
        self._observer: GraphObserver | None = None
        if graph.nodes():
            self._observer = GraphObserver(node, period=discovery_period, listening=self._listening)
            self._observer.subscribe(self._write_fetched)
            self._observer.follow(graph.lifecycle, graph.parameter_nodes())

    @property
    def waiting_for(self) -> list[str]:
        """Topics not seen on the graph yet."""
        return sorted(self._unbound)

    def _discover(self) -> None:
        if not self._unbound:
            return
        graph = dict(self.node.get_topic_names_and_types())
        for topic, qos in list(self._unbound.items()):
            types = graph.get(topic)
            if types:
                self._bind(topic, types, qos)

    def _bind(self, topic: str, types: list[str], qos: QoSProfile) -> None:
        if len(types) != 1:
            return self._refuse(topic, ", ".join(types), "it has several types")
        type_name = types[0]
        try:
            cls = message_class(type_name)
            schema = self._schema(type_name)
        except (ValueError, DefinitionError) as error:
            return self._refuse(topic, type_name, str(error))
        del self._unbound[topic]
        channel = self._writer.add_channel(topic, "cdr", schema)
        subscription = self.node.create_subscription(
            cls, topic, lambda data, c=channel, t=topic: self._write(c, t, data), qos, raw=True
        )
        self._subscriptions.append(subscription)
        self._by_topic[topic] = subscription
        self.node.get_logger().info(f"recording {topic} ({type_name})")
        return None

    def _refuse(self, topic: str, type_name: str, why: str) -> None:
        if self._refused.get(topic) != type_name:
            self._refused[topic] = type_name
            self.node.get_logger().error(f"not recording {topic} ({type_name}): {why}")

    def _schema(self, type_name: str) -> int:
        if type_name not in self._schemas:
            definition = message_definition(type_name).encode()
            self._schemas[type_name] = self._writer.add_schema(type_name, "ros2msg", definition)
        return self._schemas[type_name]

    def _write(self, channel: int, topic: str, data: bytes) -> None:
        if self._finished:
            return
        now = time.time_ns()
        self._sequence += 1
        self._writer.add_message(channel, now, data, now, self._sequence)
        self.counts[topic] += 1

    def _listening(self, topic: str) -> bool:
        """Whether `topic` (resolved) is subscribed and matched with a publisher."""
        subscription = self._by_topic.get(topic)
        return subscription is not None and subscription.get_publisher_count() > 0

    def _write_fetched(self, read: NodeRead) -> None:
        """A node's answer (or its absence) as an event, serialized as it would arrive."""
        if self._finished:
            return
        channel_name, message = read.channel, read.message
        if channel_name not in self._fetched:
            schema = self._schema(type_of(message))
            self._fetched[channel_name] = self._writer.add_channel(channel_name, "cdr", schema)
        self._write(self._fetched[channel_name], channel_name, serialize_message(message))

    def _close_chunk(self) -> None:
        if not self._finished:
            self._writer.close_chunk()

    def finish(self) -> None:
        """Write the summary and close the file (a file without it is still readable)."""
        if self._finished:
            return
        self._finished = True
        try:
            self._writer.finish()
        finally:
            self._stream.close()


class TopicNameError(ValueError):
    """A topic name ROS does not accept."""


def _resolved(node: Node, topic: str) -> str:
    try:
        return node.resolve_topic_name(topic)
    except Exception as error:  # rclpy raises its RCLError, not exported as a type
        reason = str(error).split(", at ")[0].removeprefix("failed to resolve name: ")
        raise TopicNameError(f"topic {topic!r}: {reason}") from None
