"""Rules evaluated offline over recorded messages, with the manager's own logic.

The rule engine, the firing queue (overrides, refused firings tried again, manual commands
standing) and the manager's protocol (validation, groups, relations, epochs) are the very
code the Layer manager runs; only the clock is the recording's: each message at its log
time, and the manager's timer every `tick_period` between them (a hold time ends at the
first tick after it, as live). Commands are asynchronous here, so a switch takes effect at
once instead of after the nodes' acknowledgements (milliseconds live).

States in the recording that no rule caused (an operator's commands) are played too: they
are part of the context the rules saw. `compare` then lists every difference between the
replayed states and those the live manager published.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ManagerAction,
    ParticipantReport,
    PublishState,
    Reply,
)
from contextros.protocol.manager import RECOVERY_REQUESTER, ManagerProtocol, ManagerSettings
from contextros.protocol.relations import LayerDeclaration, merge_declarations
from contextros.rules.engine import Firing, RuleEngine
from contextros.rules.firings import FiringQueue, asked
from contextros.rules.graph import GraphInputs, resolve_name
from contextros.rules.ruleset import RuleSet

MANAGER_TICK = 0.05  # the manager node's timer period (LayerManagerNode's tick_period)
REPLAY_REQUESTER = "recording"  # the state the recording started in


@dataclass(frozen=True)
class Switch:
    """A state the replayed manager published."""

    time: float
    epoch: int
    active: tuple[str, ...]
    requester: str  # "rule NAME", or who asked in the recording
    reason: str

    @property
    def cause(self) -> str:
        """`requester: reason` as `watch` and `status` print it ('-' for no reason)."""
        return f"{self.requester or '?'}: {self.reason or '-'}"


@dataclass(frozen=True)
class Refusal:
    time: float
    rule: str
    asked: str
    message: str


@dataclass
class ReplayResult:
    switches: list[Switch] = field(default_factory=list)
    refusals: list[Refusal] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # Each field a rule reads: its numeric values over time (for the timeline).
    signals: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    # (rule, start, end) of each hold time that ended in a firing.
    holds: list[tuple[str, float, float]] = field(default_factory=list)
    # Each rule topic's first message in the recording: the rules saw nothing before it.
    first_inputs: dict[str, float] = field(default_factory=dict)


class RuleReplay:
    """Feed it messages (`message`) and recorded manual states (`manual`) in time order,
    then `finish`; `result` holds the switches it made. `declarations` are the
    participants' (from the recorded statuses), `layer_files` the layer files' relations,
    as `contextros manager --layers` takes them (`declarations_from_files`). Recorded
    lifecycle states and parameters go to `graph_message` (names resolved in `namespace`,
    the live manager's; `graph_events`: whether the events are values, in a recording
    without the nodes' answers to each event: contextros.rules.graph)."""

    def __init__(
        self,
        rules: RuleSet,
        declarations: Iterable[LayerDeclaration] = (),
        *,
        layer_files: Iterable[LayerDeclaration] = (),
        start: float,
        active: Sequence[str] = (),
        tick_period: float = MANAGER_TICK,
        namespace: str = "/",
        graph_events: bool = True,
    ) -> None:
        self.rules = rules
        self.engine = RuleEngine(rules)
        self.graph = GraphInputs(
            rules.rules, lambda name: resolve_name(namespace, name), events=graph_events
        )
        self.result = ReplayResult()
        self._tick_period = tick_period
        self._next_tick = start
        self._now = start
        layer_files = tuple(layer_files)
        # Who implemented what is not recorded: every layer named anywhere counts as
        # implemented, with the relations the participants declared (recorded statuses);
        # the layer files' relations join them as they join the live manager's
        # (`ManagerSettings.layer_files`), so both compose the same way.
        implemented = merge_declarations(
            [
                *declarations,
                *(LayerDeclaration(d.name) for d in layer_files),
                *(LayerDeclaration(n) for r in rules.rules for n in r.targets()),
                *(LayerDeclaration(n) for n in active),  # someone implemented them
            ]
        )
        settings = ManagerSettings(
            layer_files=layer_files,
            manager_id="replay",
            liveness_timeout=math.inf,
            recovery_window=0.0,
            recovery_quiet=0.0,
            heartbeat_period=math.inf,
            unknown_layer_grace=0.0,
        )
        self.protocol = ManagerProtocol(start, settings, None)
        self.queue = FiringQueue(
            [rule.name for rule in rules.rules],
            self._send,
            self._relations,
            self.result.notes.append,
            automatic_requesters=(RECOVERY_REQUESTER,),
        )
        self._replies: dict[int, ActivationResult] = {}
        self._next_request = 0
        # One participant that implements every layer: validation sees all declarations.
        everything = ParticipantReport(
            node="/replay", incarnation="replay", layers=tuple(implemented.values())
        )
        self.protocol.receive_status(everything, start)
        self._run(self.protocol.tick(start))
        self._retried_at = self.protocol.state.epoch
        self._getters = {
            ref.text: (ref.topic, operator.attrgetter(".".join(ref.path)))
            for rule in rules.rules
            for ref in rule.fields
        }
        self._hold = {rule.name: rule.hold for rule in rules.rules}
        if active:
            self._command(tuple(active), (), REPLAY_REQUESTER, "the state the recording began in")

    # -- input --------------------------------------------------------------------------

    def message(self, time: float, topic: str, message: Any) -> None:
        """A message on a rule's topic (the name as the rules write it)."""
        self._advance(time)
        self.result.first_inputs.setdefault(topic, time)
        self._sample(time, topic, message)
        firings = self.engine.on_message(topic, message, time)
        for failure in self.engine.failures:
            self.result.notes.append(f"{failure} (at {time:.3f})")
        self.engine.failures.clear()
        self._fire(firings)

    def graph_message(self, time: float, channel: str, message: Any) -> bool:
        """A recorded message on `channel` (resolved) if it carries lifecycle states or
        parameters the rules read, as the live manager read them; False if not such a
        channel (contextros.rules.graph)."""
        found = self.graph.read(channel, message)
        if found is None:
            return False
        self._advance(time)
        firings = []
        for item in found:
            self.result.first_inputs.setdefault(item.source, time)
            value = item.value
            if isinstance(value, int | float) and not isinstance(value, bool):
                self.result.signals.setdefault(item.source, []).append((time, float(value)))
            firings += self.engine.on_value(item.source, value, time)
        self.result.notes += [f"{problem} (at {time:.3f})" for problem in self.graph.problems]
        self.graph.problems.clear()
        for failure in self.engine.failures:
            self.result.notes.append(f"{failure} (at {time:.3f})")
        self.engine.failures.clear()
        self._fire(firings)
        return True

    def manual(self, time: float, active: Sequence[str], requester: str, reason: str) -> None:
        """A state of the recording that no rule caused: the same command again."""
        self._advance(time)
        current = self.protocol.state.active
        off = tuple(name for name in current if name not in active)
        self._command(tuple(active), off, requester, reason)

    def finish(self, time: float) -> ReplayResult:
        self._advance(time)
        return self.result

    # -- the manager's loop ---------------------------------------------------------------

    def _advance(self, time: float) -> None:
        """The manager's timer up to `time`: hold times that end, refused firings retried."""
        while self._next_tick <= time:
            self._now = self._next_tick
            self._run(self.protocol.tick(self._now))
            self._fire(self.engine.tick(self._now))
            if self._retried_at != self.protocol.state.epoch:
                self._retried_at = self.protocol.state.epoch
                self.queue.retry()
            self._next_tick += self._tick_period
        self._now = time

    def _fire(self, firings: list[Firing]) -> None:
        for firing in firings:
            hold = self._hold.get(firing.rule, 0.0)
            if hold:
                self.result.holds.append((firing.rule, self._now - hold, self._now))
        self.queue.fire(firings)

    def _send(self, firing: Firing) -> None:
        reply = self._command(firing.activate, firing.deactivate, firing.requester, firing.reason)
        if reply.success:
            self.queue.outcome(firing, reply.message)
            return
        self.queue.outcome(firing, f"refused: {reply.message}")
        self.result.refusals.append(Refusal(self._now, firing.rule, asked(firing), reply.message))
        self.queue.refused(firing)

    def _command(
        self, activate: tuple[str, ...], deactivate: tuple[str, ...], requester: str, reason: str
    ) -> ActivationResult:
        """An asynchronous command: published (or refused) at once."""
        self._next_request += 1
        command = ActivationCommand(
            self._next_request, activate, deactivate, requester=requester, reason=reason
        )
        self._run(self.protocol.receive_command(command, self._now))
        return self._replies.pop(command.request_id)

    def _run(self, actions: list[ManagerAction]) -> None:
        for action in actions:
            if isinstance(action, PublishState):
                state = action.state
                if state.requester != RECOVERY_REQUESTER:  # the replay's own start
                    self.result.switches.append(
                        Switch(self._now, state.epoch, state.active, state.requester, state.reason)
                    )
                self.queue.published(state.requester)
            elif isinstance(action, Reply):
                self._replies[action.request_id] = action.result

    def _relations(self) -> dict[str, tuple[frozenset[str], frozenset[str]]]:
        return {
            name: (declaration.groups, declaration.excludes)
            for name, declaration in self.protocol.declarations().items()
        }

    def _sample(self, time: float, topic: str, message: Any) -> None:
        for text, (field_topic, getter) in self._getters.items():
            if field_topic != topic:
                continue
            try:
                value = getter(message)
            except AttributeError:
                continue
            if isinstance(value, bytes) and len(value) == 1:
                value = value[0]
            if isinstance(value, bool | int | float):
                self.result.signals.setdefault(text, []).append((time, float(value)))


def declaration_from_recorded(info: Any) -> LayerDeclaration:
    """A LayerInfo of a recorded participant status (decoded, fields as attributes)."""
    return LayerDeclaration(
        str(info.name),
        excludes=frozenset(map(str, info.excludes)),
        requires=frozenset(map(str, info.required)),
        group=str(info.group),
        after=frozenset(map(str, info.after)),
        # Recorded before `implies` existed: none.
        implies=frozenset(map(str, getattr(info, "implies", ()))),
    )


# -- the replay against the recording -----------------------------------------------------

# How far apart a replayed state and the recorded one may be (the manager's timer phase,
# the acknowledgements, the recorder's receive times): beyond it, a difference.
TIME_TOLERANCE = 0.25


@dataclass(frozen=True)
class RecordedState:
    """A state the live manager published, as recorded on `contextros/state`."""

    time: float
    epoch: int
    active: tuple[str, ...]
    requester: str


@dataclass(frozen=True)
class Difference:
    """Where the replay and the recording disagree. `kind`: 'layers' (other layers),
    'order' (the same layers composed in another order), 'time' (apart by more than the
    tolerance), 'missing' (a recorded state the replay did not make), 'extra' (a replayed
    state the recording does not have). `text` gives times since `start` of `compare`."""

    kind: str
    time: float
    live: RecordedState | None
    replayed: Switch | None
    text: str


def compare(
    result: ReplayResult,
    recorded: Sequence[RecordedState],
    rules: RuleSet,
    *,
    start: float,
    tolerance: float = TIME_TOLERANCE,
) -> list[Difference]:
    """Every difference between the replayed states and the recorded ones, in time order.
    States are paired in sequence by their set of layers (difflib: the longest runs that
    agree first); a paired state may still differ in order or time. A live switch that
    the replay makes late because the recording lacks its rule's first readings is not a
    time difference (a note in `result.notes` says so)."""
    from difflib import SequenceMatcher

    replayed = [s for s in result.switches if s.requester != REPLAY_REQUESTER]
    matcher = SequenceMatcher(
        None,
        [tuple(sorted(s.active)) for s in recorded],
        [tuple(sorted(s.active)) for s in replayed],
        autojunk=False,
    )
    found: list[Difference] = []
    for tag, live_from, live_to, replay_from, replay_to in matcher.get_opcodes():
        lives = recorded[live_from:live_to]
        replays = replayed[replay_from:replay_to]
        for live, switch in zip(lives, replays, strict=False):
            if tag == "equal":
                found += _paired(live, switch, result, rules, start, tolerance)
            else:
                text = (
                    f"live {_state(live.active)} at {live.time - start:.3f} s ({live.requester}), "
                    f"the replay {_state(switch.active)} at {switch.time - start:.3f} s "
                    f"({switch.requester})"
                )
                found.append(Difference("layers", live.time, live, switch, text))
        for live in lives[len(replays) :]:
            text = (
                f"live {_state(live.active)} at {live.time - start:.3f} s ({live.requester}): "
                "not in the replay"
            )
            found.append(Difference("missing", live.time, live, None, text))
        for switch in replays[len(lives) :]:
            text = (
                f"replay {_state(switch.active)} at {switch.time - start:.3f} s "
                f"({switch.requester}): not in the recording"
            )
            found.append(Difference("extra", switch.time, None, switch, text))
    return sorted(found, key=lambda difference: difference.time)


def _paired(
    live: RecordedState,
    switch: Switch,
    result: ReplayResult,
    rules: RuleSet,
    start: float,
    tolerance: float,
) -> list[Difference]:
    found = []
    at = live.time - start
    if live.active != switch.active:
        text = (
            f"live composed {_state(live.active)} at {at:.3f} s ({live.requester}), "
            f"the replay {_state(switch.active)}"
        )
        found.append(Difference("order", live.time, live, switch, text))
    apart = switch.time - live.time
    if abs(apart) > tolerance and not _unrecorded_cause(live, apart, result, rules, start):
        text = (
            f"{_state(live.active)} live at {at:.3f} s ({live.requester}), in the replay "
            f"{abs(apart):.3f} s {'later' if apart > 0 else 'earlier'} (tolerance {tolerance:g} s)"
        )
        found.append(Difference("time", live.time, live, switch, text))
    return found


def _unrecorded_cause(
    live: RecordedState, apart: float, result: ReplayResult, rules: RuleSet, start: float
) -> bool:
    """Whether the replay is late only because the recording lacks the readings that
    caused the live switch: it came before each topic of its rule had a recorded reading
    held for the rule's hold time (the recorder subscribes to a topic once it sees it on
    the graph, possibly after the manager). Then a note says so."""
    rule = next((r for r in rules.rules if f"rule {r.name}" == live.requester), None)
    if apart <= 0 or rule is None:
        return False
    # Its inputs: topics, and lifecycle states or parameters (first recorded when the
    # recorder found their node, possibly after the manager did).
    inputs = list(dict.fromkeys([*(r.topic for r in rule.fields), *(r.text for r in rule.graph)]))
    firsts = [result.first_inputs.get(name) for name in inputs]
    known = [first for first in firsts if first is not None]
    if not known or len(known) < len(firsts) or live.time >= max(known) + rule.hold:
        return False
    result.notes.append(
        f"{_state(live.active)} at {live.time - start:.3f} s came {apart:.3f} s later in the "
        f"replay: the recording has no reading of {', '.join(inputs)} from before "
        f"{max(known) - start:.3f} s, the manager had (the recorder subscribed after it)"
    )
    return True


def _state(active: Sequence[str]) -> str:
    return f"[{', '.join(active) or 'none'}]"
