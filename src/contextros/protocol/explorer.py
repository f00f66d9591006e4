"""Every interleaving, up to a bound: a breadth-first explorer of the whole protocol.

The real `ManagerProtocol` and `ParticipantProtocol` (not a model of them) with 2-3
participants, from a converged start (every node on the manager's first state), and from
each state every event that can happen next:

- a message is delivered: any message sent so far, any number of times, in any order and
  at any time. A message is never taken off the network, so this covers reordering,
  duplication, delay and loss (a lost message is one never delivered: a trace with a loss
  is the same trace without it);
- time moves one step (`TICK`): every timer fires, the manager's and then each node's
  (heartbeats, the end of recovery, liveness, deadlines, repeated proposals); between two
  steps any number of other events happen;
- a command of a script reaches the manager, each once, in any order (a synchronous one,
  atomic ones, one of which a node's application vetoes);
- one node crashes (what was sent to it is gone) and restarts as a new incarnation;
- the manager crashes and restarts from its state file.

After every event the invariants of `contextros.protocol.invariants` are checked (the same
as in the simulation). States are fingerprinted (a hash of a canonical form of every field
of every protocol object, the network and the invariants' history) so a state reached by
two interleavings is explored once, as TLC and stateright do. The search is breadth first:
the first violation found comes with a shortest trace to it.

    python -m contextros.protocol.explorer --participants 2 --depth 6

The protocol's timings are scaled to the step (`explorer_settings`): a heartbeat per step,
recovery one step, the liveness bound three, command timeouts two. Repeats of statuses and
states on a lossy link are off: they only send again what the explorer may deliver again.
One module: the world (its events) and the search (fingerprints, breadth first) are read
together, and docs/protocol.md ("Checked exhaustively") says what a bound proves.
"""

from __future__ import annotations

import argparse
import dataclasses
import pickle
import sys
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from contextros.protocol.adapter_model import deliver_proposal, state_file
from contextros.protocol.events import (
    ActivationCommand,
    ApplyState,
    ManagerAction,
    ParticipantAction,
    ParticipantReport,
    PublishHeartbeat,
    PublishProposal,
    PublishState,
    PublishStatus,
)
from contextros.protocol.invariants import (
    ALL,
    KNOWN_BROKEN,
    Invariants,
    InvariantViolation,
    add_check_all_option,
    checked_invariants,
)
from contextros.protocol.manager import ManagerProtocol, ManagerSettings
from contextros.protocol.participant import ParticipantProtocol
from contextros.protocol.simulation import LAYERS
from contextros.protocol.state import LayerState, ManagerMemory

TICK = 1.0  # one step of the explorer's clock, in protocol seconds
TIMEOUT = 2 * TICK  # every scripted command's


def explorer_settings() -> ManagerSettings:
    return ManagerSettings(
        liveness_timeout=3 * TICK,
        default_timeout=TIMEOUT,
        recovery_window=TICK,
        recovery_quiet=TICK / 2,
        heartbeat_period=TICK,
        repeats=(),
        unknown_layer_grace=TICK,
    )


def _participant(name: str, generation: int) -> ParticipantProtocol:
    return ParticipantProtocol(
        name, f"i{generation}", LAYERS, heartbeat_period=TICK, manager_timeout=3 * TICK, repeats=()
    )


# An atomic activation node 0's application vetoes, one that may commit, a synchronous one.
SCRIPT = (
    ActivationCommand(1, activate=("Fast",), atomic=True, timeout=TIMEOUT),
    ActivationCommand(2, activate=("Outdoor",), atomic=True, timeout=TIMEOUT),
    ActivationCommand(3, activate=("Night",), synchronous=True, timeout=TIMEOUT),
)


@dataclass(frozen=True)
class Bounds:
    participants: int = 2
    depth: int = 6
    node_crashes: int = 1
    manager_restarts: int = 1
    # Each reaches the manager once, in any order, at any time.
    commands: tuple[ActivationCommand, ...] = SCRIPT
    # (node index, layer): that node's application vetoes every proposal with that layer.
    vetoes: tuple[tuple[int, str], ...] = ((0, "Fast"),)
    checked: frozenset[str] = ALL - KNOWN_BROKEN
    # Another manager can be put to the same test (the tests check the checks this way).
    manager_class: type[ManagerProtocol] = ManagerProtocol


# A message on the network: (destination: a node's index or -1 for the manager, the
# node's incarnation number or the sender's index, kind, payload, the payload's identity
# beyond its equality: LayerState compares without its manager id and stamp).
Message = tuple[int, int, str, Any, tuple[Any, ...]]
_MANAGER = -1
Event = tuple[Any, ...]


@dataclass
class _Node:
    name: str
    protocol: ParticipantProtocol | None  # None: crashed
    generation: int = 0


@dataclass
class World:
    """One state of the whole system: what the explorer copies, fingerprints and steps."""

    now: float
    manager: ManagerProtocol | None
    nodes: list[_Node]
    invariants: Invariants
    manager_generation: int = 1
    saved: ManagerMemory | None = None  # the state file
    # An ordered set: the order only fixes the order events are tried in.
    network: dict[Message, None] = field(default_factory=dict)
    commands_sent: int = 0  # a bit per command of the script
    node_crashes: int = 0
    manager_restarts: int = 0

    # -- the events -------------------------------------------------------------------------

    def events(self, bounds: Bounds) -> list[Event]:
        events: list[Event] = [("tick",)]
        events += [
            ("deliver", message)
            for message in self.network
            if message[0] != _MANAGER or self.manager is not None
        ]
        if self.manager is not None:
            events += [
                ("command", index)
                for index in range(len(bounds.commands))
                if not self.commands_sent & (1 << index)
            ]
        for index, node in enumerate(self.nodes):
            if node.protocol is None:
                events.append(("restart", index))
            elif self.node_crashes < bounds.node_crashes:
                events.append(("crash", index))
        if self.manager is None:
            events.append(("restart manager",))
        elif self.manager_restarts < bounds.manager_restarts:
            events.append(("crash manager",))
        return events

    def apply(self, event: Event, bounds: Bounds) -> None:
        kind = event[0]
        if kind == "tick":
            self.now += TICK
            if self.manager is not None:
                self._manager(self.manager.tick(self.now))
            for index, node in enumerate(self.nodes):
                if node.protocol is not None:
                    self._participant(index, node.protocol.tick(self.now))
        elif kind == "deliver":
            self._deliver(event[1], bounds)
        elif kind == "command":
            assert self.manager is not None
            command = bounds.commands[event[1]]
            self.commands_sent |= 1 << event[1]
            self.invariants.command(command, self._manager_id, self.manager.live_nodes, self.now)
            self._manager(self.manager.receive_command(command, self.now))
        elif kind == "crash":
            index = event[1]
            self.nodes[index].protocol = None
            self.node_crashes += 1
            self.network = {m: None for m in self.network if m[0] != index}
        elif kind == "restart":
            node = self.nodes[event[1]]
            node.generation += 1
            node.protocol = _participant(node.name, node.generation)
            self._participant(event[1], node.protocol.announce(self.now))
        elif kind == "crash manager":
            assert self.manager is not None
            self.invariants.manager_crashed(self.manager.live_nodes, self.now)
            self.manager = None
            self.manager_restarts += 1
        elif kind == "restart manager":
            self.manager_generation += 1
            settings = replace(explorer_settings(), manager_id=self._manager_id)
            self.invariants.manager_started(
                self._manager_id, self.now, settings.liveness_timeout, self.saved is not None
            )
            self.manager = bounds.manager_class(self.now, settings, self.saved)
        else:
            raise ValueError(f"unknown event {event!r}")

    def describe(self, event: Event, bounds: Bounds) -> str:
        """The event, for a trace."""
        kind = event[0]
        if kind == "tick":
            return f"time moves to {self.now + TICK:g} s: every timer fires"
        if kind == "deliver":
            destination, _, what, payload, _ = event[1]
            if isinstance(payload, ParticipantReport):
                return f"deliver to the manager: {_report(payload)}"
            name = self.nodes[destination].name
            return f"deliver to {name}: {what} {_state(payload)}"
        if kind == "command":
            return f"command reaches the manager: {_command(bounds.commands[event[1]])}"
        if kind in ("crash", "restart"):
            return f"{kind} {self.nodes[event[1]].name}"
        if kind == "restart manager":
            return "restart the manager from its state file"
        return str(kind)

    # -- what the events do ---------------------------------------------------------------

    @property
    def _manager_id(self) -> str:
        return f"m{self.manager_generation}"

    def _send(self, destination: int, generation: int, kind: str, payload: Any) -> None:
        identity = (payload.manager_id, payload.stamp) if isinstance(payload, LayerState) else ()
        self.network[(destination, generation, kind, payload, identity)] = None

    def _deliver(self, message: Message, bounds: Bounds) -> None:
        destination, _, kind, payload, _ = message
        if destination == _MANAGER:
            assert self.manager is not None
            self._manager(self.manager.receive_status(payload, self.now))
            return
        protocol = self.nodes[destination].protocol
        assert protocol is not None  # messages to a crashed node are gone
        if kind == "state":
            self._participant(destination, protocol.receive_state(payload, self.now))
            return
        vetoed = [layer for index, layer in bounds.vetoes if index == destination]

        def application_veto(proposal: LayerState) -> str:
            refused = [layer for layer in vetoed if layer in proposal.active]
            return f"the application refuses {', '.join(refused)}" if refused else ""

        actions = deliver_proposal(self.invariants, protocol, payload, self.now, application_veto)
        self._participant(destination, actions)

    def _manager(self, actions: list[ManagerAction]) -> None:
        assert self.manager is not None
        self.saved = state_file(self.saved, self.manager, actions)
        self.invariants.manager_actions(self._manager_id, actions, self.now)
        for action in actions:
            if isinstance(action, (PublishState, PublishHeartbeat)):
                self._broadcast("state", action.state)
            elif isinstance(action, PublishProposal):
                self._broadcast("proposal", action.state)

    def _broadcast(self, kind: str, state: LayerState) -> None:
        for index, node in enumerate(self.nodes):
            if node.protocol is not None:
                self._send(index, node.generation, kind, state)

    def _participant(self, index: int, actions: list[ParticipantAction]) -> None:
        protocol = self.nodes[index].protocol
        assert protocol is not None
        self.invariants.participant_actions(protocol.node, protocol.incarnation, actions)
        for action in actions:
            if isinstance(action, ApplyState):
                self._participant(index, protocol.applied(action.state, self.now))
            elif isinstance(action, PublishStatus):
                self._send(_MANAGER, index, "status", action.report)

    def converged(self) -> bool:
        manager = self.manager
        if manager is None or manager.recovering or manager.state.epoch == 0:
            return False
        nodes = [node.protocol for node in self.nodes if node.protocol is not None]
        heard = len(manager.live_nodes) == len(nodes)
        applied = all(p.applied_epoch == manager.state.epoch for p in nodes)
        lagging = any(view.lagging for view in manager.registry(self.now).participants)
        return heard and applied and not lagging


def initial_world(bounds: Bounds) -> World:
    """A converged system: the manager recovered, every node applied its first state and
    the manager heard so. What the start-up sent is off the network (the heartbeats send
    it again)."""
    names = [f"/n{index}" for index in range(bounds.participants)]
    settings = replace(explorer_settings(), manager_id="m1")
    invariants = Invariants(bounds.checked)
    invariants.manager_started("m1", 0.0, settings.liveness_timeout, state_file=False)
    world = World(
        0.0,
        bounds.manager_class(0.0, settings),
        [_Node(n, _participant(n, 0)) for n in names],
        invariants,
    )
    for index, node in enumerate(world.nodes):
        assert node.protocol is not None
        world._participant(index, node.protocol.announce(0.0))
    delivered: set[Message] = set()
    for _ in range(50):
        waiting = [m for m in world.network if m not in delivered]
        if not waiting:
            if world.converged():
                world.network.clear()
                return world
            world.apply(("tick",), bounds)
        for message in waiting:
            delivered.add(message)
            world.apply(("deliver", message), bounds)
    raise RuntimeError("the start-up did not converge (a bug in the explorer or the protocol)")


# -- the search -------------------------------------------------------------------------------


def _canonical(value: Any) -> Any:
    """A hashable form of `value` equal for equal states: objects by their fields (caches
    and settings left out: derived or constant), dictionaries in their order (the protocol
    may depend on it), sets without one; immutable values whose equality covers every
    field as they are."""
    kind = type(value)
    how = _HOW.get(kind)
    if how is None:
        how = _HOW[kind] = _how(kind)
    if how is _AS_IS:
        return value
    if how is _ITEMS:
        return tuple(_canonical(item) for item in value)
    if how is _SET:
        return frozenset(_canonical(item) for item in value)
    if how is _DICT:
        return tuple((_canonical(k), _canonical(v)) for k, v in value.items())
    if how is _STATE:  # its equality leaves out the manager id and the stamp
        return (value, value.manager_id, value.stamp)
    fields = vars(value)
    skipped = _SKIPPED.get(kind)
    if skipped is None:  # learnt from the first object of the class
        skipped = _SKIPPED[kind] = frozenset(
            name for name in fields if name == "settings" or name.endswith("_cache")
        )
    kept = ((name, _canonical(item)) for name, item in fields.items() if name not in skipped)
    return (kind.__name__, *kept)


_AS_IS, _ITEMS, _SET, _DICT, _STATE, _OBJECT = "as is", "items", "set", "dict", "state", "object"
_HOW: dict[type, str] = {}
_SKIPPED: dict[type, frozenset[str]] = {}


def _how(kind: type) -> str:
    """How `_canonical` takes a value of this type."""
    if kind in (bool, int, float, str, type(None)):
        return _AS_IS
    if kind is LayerState:
        return _STATE
    if issubclass(kind, (tuple, list, deque)):
        return _ITEMS
    if issubclass(kind, (set, frozenset)):
        return _SET
    if issubclass(kind, dict):
        return _DICT
    if dataclasses.is_dataclass(kind):
        params = getattr(kind, "__dataclass_params__", None)
        complete = all(f.compare for f in dataclasses.fields(kind))
        if params is not None and params.frozen and params.eq and complete:
            return _AS_IS  # a frozen dataclass whose equality (and hash) covers every field
    return _OBJECT


def fingerprint(world: World) -> int:
    """A 64-bit fingerprint of the state (as TLC: two states sharing one by chance would
    be taken for one; with n states the odds are about n**2 / 2**64)."""
    return hash(
        (
            world.now,
            _canonical(world.manager),
            tuple((node.generation, _canonical(node.protocol)) for node in world.nodes),
            world.invariants.fingerprint(),
            frozenset(world.network),
            world.manager_generation,
            _canonical(world.saved),
            world.commands_sent,
            world.node_crashes,
            world.manager_restarts,
        )
    )


@dataclass
class Exploration:
    bounds: Bounds
    states: int = 0  # distinct states reached (the start included)
    transitions: int = 0  # events applied
    depth: int = 0  # the deepest level explored completely
    seconds: float = 0.0
    complete: bool = False  # no new state below the depth bound: every state was reached
    violation: InvariantViolation | None = None
    trace: tuple[str, ...] = ()  # the shortest path to the violation, its last event first

    def summary(self) -> str:
        bounds = self.bounds
        scope = (
            f"{bounds.participants} participants, {len(bounds.commands)} commands, "
            f"{bounds.node_crashes} node crash, {bounds.manager_restarts} manager restart"
        )
        head = (
            f"{self.states:,} states ({self.transitions:,} transitions) to depth "
            f"{self.depth} in {self.seconds:.1f} s; {scope}"
        )
        if self.violation is None:
            whole = " (the whole state space)" if self.complete else ""
            return f"{head}: no violation{whole}"
        steps = "\n".join(f"  {n}. {step}" for n, step in enumerate(reversed(self.trace), 1))
        return f"{head}: VIOLATION at depth {len(self.trace)}\n{self.violation}\n{steps}"


def explore(bounds: Bounds) -> Exploration:
    """Breadth first to `bounds.depth` events from the converged start."""
    started = time.perf_counter()
    result = Exploration(bounds)
    start = initial_world(bounds)
    seen = {fingerprint(start)}
    # Each state of the level being expanded, pickled (copying it is loading it), with the
    # path to it as a linked list of (event, previous).
    level: list[tuple[bytes, Any]] = [(pickle.dumps(start, pickle.HIGHEST_PROTOCOL), None)]
    result.states = 1
    for depth in range(1, bounds.depth + 1):
        following: list[tuple[bytes, Any]] = []
        for frozen, path in level:
            events = pickle.loads(frozen).events(bounds)
            for event in events:
                successor = pickle.loads(frozen)
                label = successor.describe(event, bounds)
                result.transitions += 1
                try:
                    successor.apply(event, bounds)
                except InvariantViolation as violation:
                    result.states = len(seen)
                    result.violation = violation
                    result.trace = _unwind((label, path))
                    result.seconds = time.perf_counter() - started
                    return result
                key = fingerprint(successor)
                if key not in seen:
                    seen.add(key)
                    following.append(
                        (pickle.dumps(successor, pickle.HIGHEST_PROTOCOL), (label, path))
                    )
        result.states = len(seen)
        result.depth = depth
        level = following
        if not level:
            result.complete = True
            break
    result.seconds = time.perf_counter() - started
    return result


def _unwind(path: Any) -> tuple[str, ...]:
    steps = []
    while path is not None:
        steps.append(path[0])
        path = path[1]
    return tuple(steps)


def _state(state: LayerState) -> str:
    return f"epoch {state.epoch} {list(state.active)} of {state.manager_id}"


def _report(report: ParticipantReport) -> str:
    text = f"status of {report.node} ({report.incarnation}) applied {report.applied_epoch}"
    if report.vote_epoch:
        vote = "yes" if report.vote_yes else f"no: {report.vote_reason}"
        text += f", vote on {report.vote_epoch} of {report.vote_manager_id}: {vote}"
    return text


def _command(command: ActivationCommand) -> str:
    mode = "atomic" if command.atomic else "synchronous" if command.synchronous else "async"
    return f"{mode} activate {list(command.activate)} (request {command.request_id})"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m contextros.protocol.explorer", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--participants", type=int, default=2)
    parser.add_argument("--depth", type=int, default=6)
    parser.add_argument("--node-crashes", type=int, default=1)
    parser.add_argument("--manager-restarts", type=int, default=1)
    add_check_all_option(parser)
    args = parser.parse_args(argv)
    bounds = Bounds(
        participants=args.participants,
        depth=args.depth,
        node_crashes=args.node_crashes,
        manager_restarts=args.manager_restarts,
        checked=checked_invariants(args.check_all),
    )
    result = explore(bounds)
    print(result.summary())
    return 1 if result.violation is not None else 0


if __name__ == "__main__":
    sys.exit(main())
