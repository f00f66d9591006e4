"""The ROS graph's state as rule inputs: lifecycle states and parameters (ROS-free).

    rule Degraded: SafeMode while lifecycle drivers/propeller != active
    rule Slow: Careful while param controller.max_speed < 0.5

A graph condition is one more source of values for the engine (`RuleEngine.on_value`, keyed
by `GraphRef.text`). Its values come from the node itself: `NODE/get_state` and
`NODE/get_parameters`, what the node answered when it appeared on the graph and after each
of its events, written as the messages an event would be (a TransitionEvent to the current
state, a ParameterEvent with the values as new parameters; when the node left, a
TransitionEvent to `unknown`, a ParameterEvent deleting them: no value). The manager's
`contextros.ros.graph_observer` makes these and `contextros record` writes them under these
names (stamped with the time of the read), so the replay reads what the manager read.

The events (`/parameter_events`, `NODE/transition_event`) are hints only: any process may
publish them, so the observer reads the node when one comes, and its answer counts. A
recording made before the observer (its answers unstamped, only when a node appeared) or by
another tool has no answer after each event: there the events are the values
(`GraphInputs(events=True)`, `answers_each_event`), as the manager took them then.

Either way, only the parameters the rules name are read, each value is checked (a plain
bool, number or string of at most MAX_STRING characters, of the kind the rules compare it
with: `contextros.bindings.values`), and anything else leaves the parameter without a
value, with a problem to log. The live manager and `contextros rules replay` call the same
`GraphInputs.read`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import partial
from typing import Any

from contextros.bindings.values import MAX_STRING as MAX_STRING
from contextros.bindings.values import UNKNOWN_STATE, lifecycle_state, plain_value
from contextros.language.rules import GraphRef, Literal, RuleDecl, Value
from contextros.rules.ruleset import comparisons

PARAMETER_EVENTS = "/parameter_events"
TRANSITION_EVENT = "transition_event"  # a lifecycle node's topic of transitions
GET_STATE = "get_state"  # the channel of what the node's get_state service answered
GET_PARAMETERS = "get_parameters"  # ... and its get_parameters service


@dataclass(frozen=True)
class GraphInput:
    """What a message tells of one graph value: `source` (a `GraphRef.text`) now has `value`
    (None: no value, the rules reading it see an unknown condition)."""

    source: str
    value: Value | None


def graph_topics(rules: Iterable[RuleDecl]) -> tuple[str, ...]:
    """The topics the graph conditions of `rules` listen to, named as a rule names a topic
    (relative ones resolve in the manager's namespace): `/parameter_events` and each
    lifecycle node's `NODE/transition_event`."""
    refs = [ref for rule in rules for ref in rule.graph]
    topics = [PARAMETER_EVENTS] if any(ref.kind == "param" for ref in refs) else []
    topics += [f"{ref.node}/{TRANSITION_EVENT}" for ref in refs if ref.kind == "lifecycle"]
    return tuple(dict.fromkeys(topics))


def answers_each_event(channel: str, message: Any) -> bool:
    """Whether `message` on `channel` is a node's answer stamped with the time of its read:
    written by a recorder that read the node after each of its events (module docstring)."""
    if channel.endswith(f"/{GET_STATE}"):
        return bool(getattr(message, "timestamp", 0))
    if channel.endswith(f"/{GET_PARAMETERS}"):
        stamp = getattr(message, "stamp", None)
        return bool(getattr(stamp, "sec", 0) or getattr(stamp, "nanosec", 0))
    return False


def resolve_name(namespace: str, name: str) -> str:
    """A node or topic name as the rules write it, resolved in `namespace` (no remapping;
    the live manager asks rclpy, which also applies remaps)."""
    if name.startswith("/"):
        return name
    return f"{namespace.rstrip('/')}/{name}"


class GraphInputs:
    """The graph values the rules read, by resolved names, and what each message tells of
    them. `resolve` turns a node name as written into its full name (the manager's
    namespace)."""

    def __init__(
        self, rules: Iterable[RuleDecl], resolve: Callable[[str], str], *, events: bool = True
    ) -> None:
        """`events`: whether the events themselves are values (a recording without the
        node's answers to each event: module docstring), or only the answers are."""
        rules = list(rules)
        self.lifecycle: dict[str, list[str]] = {}  # resolved node -> sources
        self.parameters: dict[tuple[str, str], list[str]] = {}  # (node, parameter) -> sources
        self._readers: dict[str, list[str]] = {}  # source -> the rules reading it
        for rule in rules:
            for ref in rule.graph:
                node = resolve(ref.node)
                if ref.kind == "lifecycle":
                    sources = self.lifecycle.setdefault(node, [])
                else:
                    sources = self.parameters.setdefault((node, ref.parameter), [])
                if ref.text not in sources:
                    sources.append(ref.text)
                readers = self._readers.setdefault(ref.text, [])
                if rule.name not in readers:
                    readers.append(rule.name)
        self._kinds = _expected_kinds(rules)
        self._channels: dict[str, Callable[[Any], list[GraphInput]]] = {}
        if self.parameters and events:
            self._channels[PARAMETER_EVENTS] = self._parameter_event
        for node in self.parameter_nodes():
            self._channels[f"{node}/{GET_PARAMETERS}"] = self._parameter_event
        for node in self.lifecycle:
            for channel in (TRANSITION_EVENT, GET_STATE) if events else (GET_STATE,):
                self._channels[f"{node}/{channel}"] = partial(self._transition, node)
        # Problems with values seen (to log), each once: (source, what was wrong).
        self.problems: list[str] = []
        self._reported: set[tuple[str, str]] = set()

    def parameter_nodes(self) -> dict[str, tuple[str, ...]]:
        """Each node whose parameters the rules read -> those parameters' names."""
        nodes: dict[str, list[str]] = {}
        for node, parameter in self.parameters:
            nodes.setdefault(node, []).append(parameter)
        return {node: tuple(names) for node, names in nodes.items()}

    def nodes(self) -> tuple[str, ...]:
        """Every node the rules read a lifecycle state or a parameter of."""
        return tuple(dict.fromkeys([*self.lifecycle, *self.parameter_nodes()]))

    def channels(self) -> tuple[str, ...]:
        """The resolved channels `read` takes (topics, and the recorded service answers)."""
        return tuple(self._channels)

    def read(self, channel: str, message: Any) -> list[GraphInput] | None:
        """What `message` on `channel` tells of the rules' graph values (None: not a
        channel of theirs). Untrusted: anything malformed gives no value, and a problem."""
        handler = self._channels.get(channel)
        return None if handler is None else handler(message)

    def absent(self, node: str) -> list[GraphInput]:
        """`node` left the graph: the values the rules read from it have none now."""
        sources = list(self.lifecycle.get(node, ()))
        sources += [s for (n, _), found in self.parameters.items() if n == node for s in found]
        return [GraphInput(source, None) for source in sources]

    # -- the messages ---------------------------------------------------------------------

    def _transition(self, node: str, event: Any) -> list[GraphInput]:
        sources = self.lifecycle.get(node, ())
        state_id = getattr(getattr(event, "goal_state", None), "id", None)
        value: str | None = None
        if state_id != UNKNOWN_STATE:  # as when the node is absent
            value = lifecycle_state(state_id)
            if value is None:
                for source in sources:
                    self._problem(
                        source, f"{node} reported an unknown lifecycle state id {state_id!r}"
                    )
        return [GraphInput(source, value) for source in sources]

    def _parameter_event(self, event: Any) -> list[GraphInput]:
        node = getattr(event, "node", None)
        if not isinstance(node, str):
            return []
        found: list[GraphInput] = []
        for kind in ("new_parameters", "changed_parameters", "deleted_parameters"):
            for parameter in getattr(event, kind, None) or ():
                name = getattr(parameter, "name", None)
                if not isinstance(name, str):
                    continue
                sources = self.parameters.get((node, name))
                if not sources:
                    continue
                deleted = kind == "deleted_parameters"
                for source in sources:
                    value = None if deleted else self._checked(source, node, parameter.value)
                    found.append(GraphInput(source, value))
        return found

    def _checked(self, source: str, node: str, value: Any) -> Value | None:
        """A parameter's value if it is one the rules can compare, else None (logged)."""
        plain, why = plain_value(value)
        if plain is None:
            self._problem(source, f"{source} on {node} is {why}: it has no value for the rules")
            return None
        kind = (
            "bool"
            if isinstance(plain, bool)
            else "number"
            if not isinstance(plain, str)
            else "string"
        )
        expected = self._kinds.get(source)
        if expected and kind not in expected:
            readers = ", ".join(self._readers.get(source, ()))
            self._problem(
                source,
                f"{source} on {node} is a {kind} ({plain!r}), rule {readers} compares it with "
                f"a {' or '.join(sorted(expected))}: its condition is unknown until it has one",
            )
            return None
        return plain

    def _problem(self, source: str, text: str) -> None:
        key = (source, text.split(":")[0])
        if key not in self._reported:
            self._reported.add(key)
            self.problems.append(text)


def _expected_kinds(rules: Iterable[RuleDecl]) -> dict[str, set[str]]:
    """Per parameter source: the kinds of value its comparisons with constants accept
    (empty: compared with a field only, any kind is tried)."""
    kinds: dict[str, set[str]] = {}
    for rule in rules:
        for comparison in comparisons(rule.condition):
            for side, other in (
                (comparison.left, comparison.right),
                (comparison.right, comparison.left),
            ):
                if not (isinstance(side, GraphRef) and side.kind == "param"):
                    continue
                accepted = kinds.setdefault(side.text, set())
                if other is None:
                    accepted.add("bool")
                elif isinstance(other, Literal):
                    value = other.value
                    if isinstance(value, bool):
                        accepted |= {"bool", "number"}
                    else:
                        accepted.add("number" if isinstance(value, float) else "string")
                else:
                    accepted |= {"bool", "number", "string"}
    return kinds
