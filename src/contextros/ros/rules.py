"""Context rules inside the Layer manager: topics bound at run time, firings as commands.

Each topic a rule reads is resolved in the manager's namespace; its message type is taken
from the ROS graph once a publisher appears (and must be the type a `topic` declaration
gives, if any), the rules' fields are checked against that type (an error names
file:line:col and the rule stays off) and only then is the topic subscribed, so no message
is ever evaluated against a field that does not exist. See docs/rules.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from contextros.language.diagnostics import Diagnostic
from contextros.protocol import LayerState
from contextros.protocol.manager import RECOVERY_REQUESTER
from contextros.ros.message_types import field_kind, message_class
from contextros.rules import Firing, RuleEngine, RuleSet
from contextros.rules.ruleset import FieldKind

__all__ = ["RULE_QOS", "RuleRunner", "field_kind", "message_class"]

# Best effort matches reliable and best-effort publishers alike; sensors are noisy anyway.
RULE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.BEST_EFFORT
)


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
    ) -> None:
        self.node = node
        self.rules = rules
        self.engine = RuleEngine(rules)
        self._submit = submit
        self._relations = relations
        self._unbound = {topic: node.resolve_topic_name(topic) for topic in self.engine.topics()}
        self._failed: dict[str, str] = {}  # topic -> type it failed with (not retried)
        # Topics bound so far: (field lookup, type name), to check fields compared across topics.
        self._known: dict[str, tuple[Callable[[tuple[str, ...]], FieldKind], str]] = {}
        self._subscriptions: list[Any] = []
        self.errors: list[Diagnostic] = []
        # Firings the manager refused (a relation, say): tried again after each new state
        # until one succeeds or the rule fires anew (docs/rules.md, "refused firings"), or
        # a state no rule caused (an operator's command) is published: that one stands.
        self._refused: dict[str, Firing] = {}
        self._requesters = {f"rule {rule.name}" for rule in rules.rules} | {RECOVERY_REQUESTER}
        self._manual_states = 0  # states published that no rule caused, so far
        self._submitted_at: dict[str, int] = {}  # rule -> _manual_states when it last fired
        self._discovery = node.create_timer(discovery_period, self._discover)
        for rule in rules.rules:
            node.get_logger().info(f"rule {rule.name} ({rules.where(rule)}): {rule.text}")
        self._discover()

    # -- binding ------------------------------------------------------------------------

    def _discover(self) -> None:
        if not self._unbound:
            self._discovery.cancel()
            return
        graph = dict(self.node.get_topic_names_and_types())
        for topic, resolved in list(self._unbound.items()):
            types = graph.get(resolved)
            if not types:
                continue
            if len(types) != 1:
                self._refuse(topic, ", ".join(types), f"topic {resolved} has several types")
                continue
            self._bind(topic, resolved, types[0])

    def _refuse(self, topic: str, type_name: str, why: str) -> None:
        if self._failed.get(topic) != type_name:
            self.node.get_logger().error(f"rules on {topic} stay off: {why}")
            self._failed[topic] = type_name

    def _bind(self, topic: str, resolved: str, type_name: str) -> None:
        mismatch = self.rules.type_mismatch(topic, resolved, type_name)
        if mismatch is not None:
            # Not bound: a publisher of the declared type may come instead (checked again).
            if self._failed.get(topic) != type_name:
                self.errors.append(mismatch)
                self.node.get_logger().error(f"rules on {resolved} stay off:\n{mismatch.render()}")
                self._failed[topic] = type_name
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
            del self._unbound[topic]
            for problem in problems:
                self.node.get_logger().error(f"rules on {resolved} stay off:\n{problem.render()}")
            return
        del self._unbound[topic]
        self._failed.pop(topic, None)  # refused earlier (another type): its messages count now
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
        self._fire(firings)

    def tick(self) -> None:
        self._fire(self.engine.tick(time.monotonic()))

    def refused(self, firing: Firing) -> None:
        """The manager refused `firing`: keep it for the next state (unless newer), unless a
        manual command set a state since it was submitted (that command stands)."""
        if self._submitted_at.get(firing.rule, self._manual_states) != self._manual_states:
            self._dropped(firing)
            return
        self._refused.setdefault(firing.rule, firing)

    def published(self, state: LayerState) -> None:
        """The manager published `state`. One that no rule and no recovery caused is a manual
        command: it stands until a rule's condition changes, so the refused firings, older
        than it, are dropped (docs/rules.md, "manual commands and rules")."""
        if state.requester in self._requesters:
            return
        self._manual_states += 1
        for firing in self._refused.values():
            self._dropped(firing)
        self._refused.clear()

    def _dropped(self, firing: Firing) -> None:
        self.node.get_logger().info(
            f"{firing.requester}: its refused firing is dropped, a manual command came after "
            "it (it acts again when its condition changes)"
        )

    def retry(self) -> None:
        """A new state: the refused firings may pass now (in file order)."""
        waiting = sorted(self._refused.values(), key=lambda f: f.priority)
        self._refused.clear()
        for firing in waiting:
            self._send(firing)

    def _send(self, firing: Firing) -> None:
        self._submitted_at[firing.rule] = self._manual_states
        self._submit(firing)

    def _fire(self, firings: list[Firing]) -> None:
        if not firings:
            return
        if len(firings) > 1:
            from contextros.rules import resolve

            firings, overridden = resolve(firings, self._relations())
            for firing in overridden:
                self.node.get_logger().warning(
                    f"{firing.requester} ({firing.reason}) overridden by a rule declared "
                    "before it (contradicting targets)"
                )
        for firing in firings:
            self._refused.pop(firing.rule, None)  # superseded by the rule's new value
            self._send(firing)
