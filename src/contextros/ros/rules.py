"""Context rules inside the Layer manager: topics bound at run time, firings as commands.

Each topic a rule reads is resolved in the manager's namespace; its message type is taken
from the ROS graph once a publisher appears (and must be the type a `topic` declaration
gives, if any), the rules' fields are checked against that type (an error names
file:line:col and the rule stays off) and only then is the topic subscribed, so no message
is ever evaluated against a field that does not exist. A topic with no publisher after
`UNPUBLISHED_GRACE` is logged once (a misspelt name leaves its rules waiting for ever).

Lifecycle states and parameters (`lifecycle NODE`, `param NODE.PARAMETER`) come from the
nodes' get_state / get_parameters services, read by the manager's `GraphObserver` when a
node appears and after each of its events (hints only), and go through the same
`contextros.rules.graph.GraphInputs` as the replay. See docs/rules.md.
"""

from __future__ import annotations

import difflib
import time
from collections.abc import Callable
from typing import Any

from contextros_interfaces.msg import RuleInfo
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from contextros.language.diagnostics import Diagnostic
from contextros.protocol import LayerState
from contextros.protocol.manager import RECOVERY_REQUESTER
from contextros.ros.graph_observer import GraphObserver, NodeRead
from contextros.ros.message_types import field_kind, message_class
from contextros.rules import Firing, RuleEngine, RuleSet
from contextros.rules.firings import FiringQueue
from contextros.rules.graph import GraphInputs
from contextros.rules.ruleset import FieldKind

__all__ = ["RULE_QOS", "UNPUBLISHED_GRACE", "RuleRunner", "field_kind", "message_class"]

# Best effort matches reliable and best-effort publishers alike; sensors are noisy anyway.
RULE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT
)
# Seconds after the manager's start before a topic the rules read and no node publishes is
# logged: a robot's sensor nodes are up by then (started with the manager, or before it),
# so a topic still missing is more likely misspelt or not launched than slow.
UNPUBLISHED_GRACE = 5.0


class RuleRunner:
    """Binds a rule set to the topics of `node` (the manager) and hands firings to `submit`."""

    def __init__(
        self,
        node: Node,
        rules: RuleSet,
        submit: Callable[[Firing], object],
        relations: Callable[[], Any],
        *,
        discovery_period: float = 0.2,
        unpublished_grace: float = UNPUBLISHED_GRACE,
        graph: Callable[[], GraphObserver] | None = None,
    ) -> None:
        """`graph` gives the observer of lifecycle states and parameters to read them from
        (the manager's, shared with its bindings; by default one of the runner's own)."""
        self.node = node
        self.rules = rules
        self.engine = RuleEngine(rules)
        self._unbound = {topic: node.resolve_topic_name(topic) for topic in self.engine.topics()}
        self._failed: dict[str, str] = {}  # topic -> type it failed with (not retried)
        self._failed_why: dict[str, str] = {}  # topic -> why its rules are off
        # Topics bound so far: (field lookup, type name), to check fields compared across topics.
        self._known: dict[str, tuple[Callable[[tuple[str, ...]], FieldKind], str]] = {}
        self._subscriptions: list[Any] = []
        self.errors: list[Diagnostic] = []
        self._rules_by_name = {rule.name: rule for rule in rules.rules}
        # Overridden, refused and retried firings (docs/rules.md, "refused firings").
        self.firings = FiringQueue(
            self._rules_by_name,
            submit,
            relations,
            lambda text: node.get_logger().info(text),
            automatic_requesters=(RECOVERY_REQUESTER,),
        )
        self._started = time.monotonic()
        self._unpublished_grace = unpublished_grace
        self._unpublished_logged: set[str] = set()  # topics already logged as unpublished
        self._discovery = node.create_timer(discovery_period, self._discover)
        for rule in rules.rules:
            # The file as given on the command line (`where`, in reasons on the wire: its name).
            node.get_logger().info(f"rule {rule.name} ({rule.path}:{rule.at.line}): {rule.text}")
        self._discover()
        self.graph = GraphInputs(rules.rules, node.resolve_topic_name, events=False)
        if self.graph.nodes():
            observer = graph() if graph else GraphObserver(node, period=discovery_period)
            observer.subscribe(self._on_read)
            observer.follow(self.graph.lifecycle, self.graph.parameter_nodes())
            nodes = ", ".join(self.graph.nodes())
            node.get_logger().info(f"rules read the lifecycle states and parameters of {nodes}")

    # -- binding ------------------------------------------------------------------------

    def _discover(self) -> None:
        if not self._unbound:
            self._discovery.cancel()
            return
        graph = dict(self.node.get_topic_names_and_types())
        for topic, resolved in list(self._unbound.items()):
            types = graph.get(resolved)
            if not types:
                self._unpublished(topic, resolved, graph)
                continue
            if len(types) != 1:
                self._refuse(topic, ", ".join(types), f"topic {resolved} has several types")
                continue
            self._bind(topic, resolved, types[0])

    def _unpublished(self, topic: str, resolved: str, graph: dict[str, list[str]]) -> None:
        """Log, once and after the grace period, that no node publishes `resolved`."""
        waited = time.monotonic() - self._started
        if waited < self._unpublished_grace or topic in self._unpublished_logged:
            return
        self._unpublished_logged.add(topic)
        readers = [
            rule.name for rule in self.rules.rules if any(r.topic == topic for r in rule.fields)
        ]
        close = difflib.get_close_matches(resolved, list(graph), n=3)
        hint = f" Published topics with a close name: {', '.join(close)}." if close else ""
        reads = (
            f"rule {readers[0]} reads it"
            if len(readers) == 1
            else f"rules {', '.join(readers)} read it"
        )
        self.node.get_logger().warning(
            f"rules on {resolved} wait: no node has published it in the {waited:.0f} s since "
            f"the manager started ({reads}). Is its name misspelt, or its publisher not "
            f"started?{hint}"
        )

    def _refuse(self, topic: str, type_name: str, why: str) -> None:
        if self._failed.get(topic) != type_name:
            self.node.get_logger().error(f"rules on {topic} stay off: {why}")
            self._failed[topic] = type_name
            self._failed_why[topic] = why

    def _bind(self, topic: str, resolved: str, type_name: str) -> None:
        # The graph's type may be only its subscribers' (nothing publishes the topic yet).
        published = self.node.count_publishers(resolved) > 0
        mismatch = self.rules.type_mismatch(topic, resolved, type_name, published=published)
        if mismatch is not None:
            # Not bound: a publisher of the declared type may come instead (checked again).
            seen = type_name if published else f"{type_name} (subscribed)"
            if self._failed.get(topic) != seen:
                self.errors.append(mismatch)
                self.node.get_logger().error(f"rules on {resolved} stay off:\n{mismatch.render()}")
                self._failed[topic] = seen
                self._failed_why[topic] = mismatch.message
            return
        try:
            cls = message_class(type_name)
        except ValueError as error:
            self._refuse(topic, type_name, f"topic {resolved}: {error}")
            return

        def lookup(path: tuple[str, ...]) -> FieldKind:
            return field_kind(cls, path)

        problems = self.rules.check_fields(topic, lookup, type_name, self._known)
        if problems:
            self.errors += problems
            self._failed[topic] = type_name
            self._failed_why[topic] = "; ".join(problem.message for problem in problems)
            del self._unbound[topic]
            for problem in problems:
                self.node.get_logger().error(f"rules on {resolved} stay off:\n{problem.render()}")
            return
        del self._unbound[topic]
        # Refused earlier (another type): its messages count now.
        self._failed.pop(topic, None)
        self._failed_why.pop(topic, None)
        self._known[topic] = (lookup, type_name)
        self._subscriptions.append(
            self.node.create_subscription(
                cls, resolved, lambda msg, topic=topic: self._on_message(topic, msg), RULE_QOS
            )
        )
        self.node.get_logger().info(f"rules read {resolved} ({type_name})")

    # -- evaluation ---------------------------------------------------------------------

    def _on_message(self, topic: str, message: Any) -> None:
        # Anything the network sends must not stop the manager: a rule whose evaluation
        # raises is logged and turned off by the engine; the other rules keep running.
        if topic in self._failed:
            return
        try:
            firings = self.engine.on_message(topic, message, time.monotonic())
        finally:
            for failure in self.engine.failures:
                self.node.get_logger().error(f"{failure} (a message on {topic})")
            self.engine.failures.clear()
        self.firings.fire(firings)

    def _on_read(self, read: NodeRead) -> None:
        """What a node answered (or that it left): the rules reading its values."""
        channel, message = read.channel, read.message
        now = time.monotonic()
        firings: list[Firing] = []
        try:
            for found in self.graph.read(channel, message) or ():
                firings += self.engine.on_value(found.source, found.value, now)
        finally:
            for problem in self.graph.problems:
                self.node.get_logger().error(f"rules: {problem}")
            self.graph.problems.clear()
            for failure in self.engine.failures:
                self.node.get_logger().error(f"{failure} (a value from {channel})")
            self.engine.failures.clear()
        self.firings.fire(firings)

    def tick(self) -> None:
        self.firings.fire(self.engine.tick(time.monotonic()))

    def refused(self, firing: Firing) -> None:
        self.firings.refused(firing)

    def published(self, state: LayerState) -> None:
        self.firings.published(state.requester)

    def retry(self) -> None:
        self.firings.retry()

    def outcome(self, firing: Firing, text: str) -> None:
        """What the manager made of `firing` (shown by `status` and the dashboard)."""
        self.firings.outcome(firing, text)

    def infos(self) -> list[Any]:
        """Every rule's value, hold timer, hysteresis state and last firing (RuleInfo)."""
        infos = []
        for report in self.engine.report(time.monotonic()):
            rule = self._rules_by_name[report.name]
            off = [self._failed_why[ref.topic] for ref in rule.fields if ref.topic in self._failed]
            error = report.error or (off[0] if off else "")
            last_firing, last_outcome = self.firings.last.get(report.name, ("", ""))
            infos.append(
                RuleInfo(
                    name=report.name,
                    where=report.where,
                    text=report.text,
                    value="off" if error else report.value_text,
                    settled="" if report.settled is None else str(report.settled).lower(),
                    holding=report.holding,
                    hold_left=report.hold_left,
                    hold=report.hold,
                    hysteresis=report.hysteresis,
                    relaxed=report.relaxed,
                    readings=[f"{name} = {value}" for name, value in report.readings],
                    error=error,
                    last_firing=last_firing,
                    last_outcome=last_outcome,
                )
            )
        return infos
