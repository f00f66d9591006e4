"""The whole protocol at scale, simulated: one manager, N participants and a network that
delays, loses, duplicates and reorders messages, cuts nodes off, crashes and restarts them
(the manager too), all drawn from one seed so that any run replays exactly.

A run has four phases: start-up (every participant announces, the manager recovers), a
clean phase of back-to-back synchronous activations (measured: messages, manager CPU and
time per activation), a fault phase (commands of every kind while the faults happen) and
a heal (faults stop, crashed nodes are back): the system must converge, and a last
synchronous activation must be acknowledged by every node. Checked all along (the checks
of `contextros.protocol.invariants`, shared with the explorer):

- no epoch names two layer sets (among states published and applied, and proposals);
- no participant goes back: each incarnation applies strictly increasing epochs;
- an aborted atomic activation changed nothing: its epoch is never published nor applied;
- answers are exact: one answer per command; a success carries its epoch's layers and every
  node it names as acknowledging applied that epoch; a synchronous success names every node
  live when the command arrived (not dropped since) and, after a restart, every node the
  manager knew live before it; in the clean phases every synchronous activation succeeds,
  acknowledged by all N nodes;
- a node votes once per proposal, and its application's vetoes are asked once (the
  manager's state file and the vetoes are handled as the adapter does: `adapter_model`);
- after the heal, within `converge_within` seconds, every node is live in the manager and
  applied its epoch.

    python -m contextros.protocol.simulation --seed 123 --participants 1000

A violation raises `InvariantViolation`, whose message names the seed and the command that
replays it. What the protocol is known to break (`invariants.KNOWN_BROKEN`) is left out
unless `--check-all`. Time is simulated (no sleeping); the manager's CPU is measured for real.
"""

from __future__ import annotations

import argparse
import hashlib
import heapq
import math
import random
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

from contextros.protocol.adapter_model import deliver_proposal, state_file
from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ApplyState,
    ManagerAction,
    ParticipantAction,
    ParticipantDropped,
    ParticipantReport,
    PublishHeartbeat,
    PublishProposal,
    PublishState,
    PublishStatus,
    Reply,
)
from contextros.protocol.invariants import (
    ALL,
    KNOWN_BROKEN,
    Invariants,
    add_check_all_option,
    checked_invariants,
)
from contextros.protocol.invariants import (
    InvariantViolation as InvariantViolation,  # raised by `simulate`
)
from contextros.protocol.manager import ManagerProtocol, ManagerSettings
from contextros.protocol.participant import DEFAULT_HEARTBEAT_PERIOD, ParticipantProtocol
from contextros.protocol.relations import LayerDeclaration
from contextros.protocol.state import LayerState, ManagerMemory

LAYERS = (
    LayerDeclaration("Indoor", group="location"),
    LayerDeclaration("Outdoor", group="location"),
    LayerDeclaration("Night"),
    LayerDeclaration("Slow", excludes=frozenset({"Fast"})),
    LayerDeclaration("Fast"),
)
MANAGER_TICK = 0.05  # the rclpy manager node's timer period

# What travels, as the first item of a scheduled event.
_TO_MANAGER, _STATE, _PROPOSAL, _WAKE, _MANAGER_TICK, _SCRIPT = range(6)


@dataclass(frozen=True)
class Faults:
    """What the network and the processes do wrong during the fault phase."""

    loss: float = 0.2
    duplication: float = 0.1
    # One-way delay, uniform in this range: a range wider than the gaps between messages
    # reorders them.
    delay: tuple[float, float] = (0.001, 0.25)
    # Each: a random tenth of the nodes (at least one) cut off for 0.5 to 5 s.
    partitions: int = 2
    # Each: a node's process dies and a new incarnation starts 0.2 to 5 s later.
    crashes: int = 3
    # Each: the manager dies and restarts from its state file 0.2 to 2 s later.
    manager_restarts: int = 1
    duration: float = 10.0
    commands: int = 12


@dataclass(frozen=True)
class Scenario:
    participants: int = 10
    seed: int = 0
    # Back-to-back synchronous activations on a clean link, measured.
    clean_activations: int = 5
    faults: Faults = Faults()
    clean_delay: tuple[float, float] = (0.0005, 0.002)
    # Seconds after the heal by which every node must be live and on the manager's epoch:
    # a dropped node rejoins at its next heartbeat, a lagging one gets the manager's.
    converge_within: float = 10.0
    settings: ManagerSettings = field(default_factory=ManagerSettings)
    # The invariants checked (contextros.protocol.invariants): by default all but those
    # the protocol is known to break (`KNOWN_BROKEN`).
    checked: frozenset[str] = ALL - KNOWN_BROKEN

    def replay_command(self) -> str:
        everything = " --check-all" if self.checked == ALL else ""
        return (
            f"python -m contextros.protocol.simulation --seed {self.seed} "
            f"--participants {self.participants}{everything}"
        )


@dataclass
class SimulationReport:
    scenario: Scenario
    # The clean phase, per synchronous activation.
    messages_per_activation: float = 0.0
    manager_cpu_per_activation: float = 0.0  # seconds of this process's CPU
    activation_time: float = 0.0  # simulated seconds, command to answer
    # Per simulated second with nothing happening (heartbeats both ways).
    idle_messages_per_second: float = 0.0
    idle_manager_cpu_per_second: float = 0.0
    time_to_converge: float = 0.0  # simulated seconds after the heal
    # The heartbeat period the manager asked for when idle, its liveness bound, and the
    # longest time from a node's crash to its drop (a few nodes, crashed at the end).
    status_period: float = 0.0
    liveness_bound: float = 0.0
    detection_time: float = 0.0
    commands: int = 0
    answers: int = 0
    aborted_atomic: int = 0
    messages: int = 0
    events: int = 0
    wall_time: float = 0.0
    # A digest of everything that happened: equal for two runs of one scenario.
    trace: str = ""


@dataclass
class _Node:
    """One participant's process as the simulation sees it."""

    name: str
    protocol: ParticipantProtocol
    generation: int = 0  # its incarnation number: events for an older one are void
    alive: bool = True
    next_wake: float = 0.0
    veto_next: bool = False


@dataclass
class _Command:
    command: ActivationCommand
    manager_generation: int
    answer: ActivationResult | None = None


@dataclass
class _Counters:
    messages: int = 0
    manager_cpu: float = 0.0


class Simulation:
    def __init__(
        self, scenario: Scenario, manager_class: type[ManagerProtocol] = ManagerProtocol
    ) -> None:
        self.scenario = scenario
        # Another manager can be put to the same test (the tests check the checks this way).
        self.manager_class = manager_class
        self.rng = random.Random(scenario.seed)
        self.now = 0.0
        self._queue: list[tuple[float, int, int, int, int, object]] = []
        self._sequence = 0
        self._faulty = False
        self._cut: set[int] = set()
        self.counters = _Counters()
        self._events = 0
        self._trace = hashlib.sha256()
        self.nodes = [
            _Node(f"/robot/node{index}", self._participant(f"/robot/node{index}", 0))
            for index in range(scenario.participants)
        ]
        self.invariants = Invariants(scenario.checked, describe=self._describe)
        self.manager_generation = 0
        self.manager: ManagerProtocol | None = self._start_manager(None)
        self.state_file: ManagerMemory | None = None
        self.commands: dict[int, _Command] = {}
        self._request_id = 0
        self.dropped: dict[str, float] = {}  # node -> when the manager last dropped it

    # -- set-up ---------------------------------------------------------------------------

    def _participant(self, name: str, generation: int) -> ParticipantProtocol:
        return ParticipantProtocol(name, f"i{generation}", LAYERS)

    def _start_manager(self, saved: ManagerMemory | None) -> ManagerProtocol:
        self.manager_generation += 1
        settings = replace(self.scenario.settings, manager_id=f"m{self.manager_generation}")
        self._schedule(self.now + MANAGER_TICK, _MANAGER_TICK, generation=self.manager_generation)
        self.invariants.manager_started(
            settings.manager_id, self.now, settings.liveness_timeout, saved is not None
        )
        return self.manager_class(self.now, settings, saved)

    # -- the event queue ------------------------------------------------------------------

    def _schedule(
        self, at: float, kind: int, target: int = 0, generation: int = 0, payload: object = None
    ) -> None:
        self._sequence += 1
        heapq.heappush(self._queue, (at, self._sequence, kind, target, generation, payload))

    def _delay(self) -> float:
        low, high = self.scenario.faults.delay if self._faulty else self.scenario.clean_delay
        return low + self.rng.random() * (high - low)

    def _send(self, kind: int, target: int, generation: int, payload: object) -> None:
        """One message over the simulated network (to a participant, or -1: the manager)."""
        self.counters.messages += 1
        node = target if kind != _TO_MANAGER else generation
        if node in self._cut:
            return
        copies = 1
        if self._faulty:
            faults = self.scenario.faults
            if self.rng.random() < faults.loss:
                return
            if self.rng.random() < faults.duplication:
                copies = 2
        for _ in range(copies):
            self._schedule(self.now + self._delay(), kind, target, generation, payload)

    def _wake_when_due(self, index: int) -> None:
        """Wake the node's heartbeat timer when its tick has something to do: at a repeat,
        else at the first beat of its timer (every `heartbeat_period`) when something is
        due; the beats in between would do nothing (`next_tick`)."""
        protocol = self.nodes[index].protocol
        repeat, due = protocol.next_repeat, protocol.next_tick
        if repeat is not None and (due is None or repeat <= due):
            self._wake(index, repeat)
            return
        period = protocol.heartbeat_period
        beats = 1 if due is None else max(1, math.ceil((due - self.now) / period - 1e-9))
        self._wake(index, self.now + beats * period)

    def _wake(self, index: int, at: float) -> None:
        node = self.nodes[index]
        if at < node.next_wake or node.next_wake <= self.now:
            node.next_wake = at
            self._schedule(at, _WAKE, index, node.generation)

    # -- running --------------------------------------------------------------------------

    def run_until(
        self, end: float, done: Callable[[], bool] | None = None, check_every: float = 0.0
    ) -> bool:
        """Process events up to `end` (simulated seconds); stop early once `done()`, asked
        after every event or, for a costly question, every `check_every` seconds."""
        checked = self.now
        while self._queue and self._queue[0][0] <= end:
            at, _, kind, target, generation, payload = heapq.heappop(self._queue)
            self.now = at
            self._events += 1
            self._dispatch(kind, target, generation, payload)
            if done is not None and at - checked >= check_every:
                checked = at
                if done():
                    return True
        self.now = max(self.now, end)
        return done() if done is not None else False

    def _dispatch(self, kind: int, target: int, generation: int, payload: object) -> None:
        if kind == _TO_MANAGER:
            assert isinstance(payload, ParticipantReport)
            if self.manager is not None:
                self._manager_call(lambda m: m.receive_status(payload, self.now))
        elif kind == _MANAGER_TICK:
            if self.manager is not None and generation == self.manager_generation:
                self._manager_call(lambda m: m.tick(self.now))
                self._schedule(self.now + MANAGER_TICK, _MANAGER_TICK, generation=generation)
        elif kind == _SCRIPT:
            assert callable(payload)
            payload()
        else:
            node = self.nodes[target]
            if not node.alive or generation != node.generation:
                return
            protocol = node.protocol
            if kind == _WAKE:
                if self.now < node.next_wake:
                    return  # replaced by an earlier wake
                node.next_wake = 0.0
                self._run_participant(target, protocol.tick(self.now))
            elif kind == _STATE:
                assert isinstance(payload, LayerState)
                self._run_participant(target, protocol.receive_state(payload, self.now))
            else:
                assert isinstance(payload, LayerState)

                def application_veto(proposal: LayerState) -> str:
                    if node.veto_next and proposal.epoch > protocol.newest_epoch:
                        node.veto_next = False
                        return "busy (simulated veto)"
                    return ""

                actions = deliver_proposal(
                    self.invariants, protocol, payload, self.now, application_veto
                )
                self._run_participant(target, actions)
            self._wake_when_due(target)

    def _manager_call(self, call: Callable[[ManagerProtocol], list[ManagerAction]]) -> None:
        manager = self.manager
        assert manager is not None
        started = time.process_time()
        actions = call(manager)
        self.counters.manager_cpu += time.process_time() - started
        self.state_file = state_file(self.state_file, manager, actions)
        self._run_manager(actions)

    def _run_manager(self, actions: Sequence[ManagerAction]) -> None:
        self.invariants.manager_actions(f"m{self.manager_generation}", actions, self.now)
        for action in actions:
            if isinstance(action, PublishState):
                state = action.state
                self._trace.update(f"S{state.epoch}{state.active}".encode())
                self._broadcast(_STATE, state)
            elif isinstance(action, PublishHeartbeat):
                self._broadcast(_STATE, action.state)
            elif isinstance(action, PublishProposal):
                self._broadcast(_PROPOSAL, action.state)
            elif isinstance(action, Reply):
                self._answer(action.request_id, action.result)
            elif isinstance(action, ParticipantDropped):
                self.dropped[action.node] = self.now

    def _broadcast(self, kind: int, state: LayerState) -> None:
        for index, node in enumerate(self.nodes):
            self._send(kind, index, node.generation, state)

    def _run_participant(self, index: int, actions: Sequence[ParticipantAction]) -> None:
        node = self.nodes[index]
        self.invariants.participant_actions(node.name, node.protocol.incarnation, actions)
        for action in actions:
            if isinstance(action, ApplyState):
                self._run_participant(index, node.protocol.applied(action.state, self.now))
            elif isinstance(action, PublishStatus):
                self._send(_TO_MANAGER, -1, index, action.report)

    # -- invariants -----------------------------------------------------------------------

    def _describe(self, what: str) -> str:
        scenario = self.scenario
        return (
            f"seed {scenario.seed}, {scenario.participants} participants, t={self.now:.3f} s: "
            f"{what}\nreplay: {scenario.replay_command()}"
        )

    def _fail(self, what: str) -> None:
        raise InvariantViolation(self._describe(what))

    def _answer(self, request_id: int, result: ActivationResult) -> None:
        asked = self.commands[request_id]  # the invariants checked it was asked, once
        asked.answer = result
        self._trace.update(f"R{request_id}{result.success}{result.epoch}".encode())

    def _converged(self) -> bool:
        manager = self.manager
        if manager is None or manager.recovering or manager.state.epoch == 0:
            return False
        epoch = manager.state.epoch
        if any(node.protocol.applied_epoch != epoch for node in self.nodes):
            return False
        return len(manager.live_nodes) == len(self.nodes) and not manager.conflicts()

    # -- the script -----------------------------------------------------------------------

    def command(self, **fields: object) -> int:
        assert self.manager is not None
        self._request_id += 1
        command = ActivationCommand(self._request_id, requester="simulation", **fields)  # type: ignore[arg-type]
        self.commands[self._request_id] = _Command(command, self.manager_generation)
        self._trace.update(f"C{command}".encode())
        manager_id = f"m{self.manager_generation}"
        self.invariants.command(command, manager_id, self.manager.live_nodes, self.now)
        self._manager_call(lambda m: m.receive_command(command, self.now))
        return self._request_id

    def _sync_activation(self, index: int) -> ActivationResult:
        """A synchronous activation on a clean link, run until answered (exact or failed)."""
        layer = ("Indoor", "Outdoor")[index % 2]
        night = ("Night",) if index % 3 == 0 else ()
        request = self.command(activate=(layer, *night), synchronous=True, timeout=5.0)
        self.run_until(self.now + 10.0, lambda: self.commands[request].answer is not None)
        answer = self.commands[request].answer
        if answer is None:
            self._fail(f"synchronous activation {request} got no answer within 10 s")
        assert answer is not None
        every = tuple(sorted(node.name for node in self.nodes))
        if not answer.success or answer.acknowledged != every:
            self._fail(
                f"clean synchronous activation {request} not exact: {answer.message} "
                f"({len(answer.acknowledged)} of {len(every)} acknowledged)"
            )
        return answer

    def _crash(self, index: int, down_for: float) -> None:
        node = self.nodes[index]
        if not node.alive:
            return
        node.alive = False

        def restart() -> None:
            node.generation += 1
            node.protocol = self._participant(node.name, node.generation)
            node.alive, node.next_wake = True, 0.0
            self._run_participant(index, node.protocol.announce(self.now))
            self._wake(index, self.now + self.rng.random() * node.protocol.heartbeat_period)

        self._schedule(self.now + down_for, _SCRIPT, payload=restart)

    def _restart_manager(self, down_for: float) -> None:
        if self.manager is None:
            return
        self.invariants.manager_crashed(self.manager.live_nodes, self.now)
        self.manager = None

        def restart() -> None:
            if self.manager is None:
                self.manager = self._start_manager(self.state_file)

        self._schedule(self.now + down_for, _SCRIPT, payload=restart)

    def _cut_off(self, indices: list[int], cut_for: float) -> None:
        self._cut.update(indices)

        def heal() -> None:
            self._cut.difference_update(indices)

        self._schedule(self.now + cut_for, _SCRIPT, payload=heal)

    def _random_command(self) -> None:
        if self.manager is None:
            return  # a client finds no manager: it times out, nothing is asked
        rng = self.rng
        mode = rng.choice(("async", "sync", "atomic"))
        layers = [d.name for d in LAYERS]
        activate = (rng.choice(layers),)
        deactivate = tuple(
            n for n in (rng.choice(layers),) if n not in activate and rng.random() < 0.3
        )
        if mode == "atomic" and rng.random() < 0.3:
            self.nodes[rng.randrange(len(self.nodes))].veto_next = True
        expect = (self.nodes[rng.randrange(len(self.nodes))].name,) if rng.random() < 0.3 else ()
        self.command(
            activate=activate,
            deactivate=deactivate,
            synchronous=mode == "sync",
            atomic=mode == "atomic",
            timeout=rng.uniform(0.5, 3.0),
            expect_nodes=expect,
        )

    def _script_faults(self) -> None:
        faults, rng, start = self.scenario.faults, self.rng, self.now
        n = len(self.nodes)

        def at(offset: float, action: Callable[[], None]) -> None:
            self._schedule(start + offset, _SCRIPT, payload=action)

        for _ in range(faults.commands):
            at(rng.uniform(0, faults.duration), self._random_command)
        for _ in range(faults.partitions):
            chosen = sorted(rng.sample(range(n), max(1, n // 10)))
            cut_for = rng.uniform(0.5, 5.0)
            at(rng.uniform(0, faults.duration), partial(self._cut_off, chosen, cut_for))
        for _ in range(faults.crashes):
            index, down = rng.randrange(n), rng.uniform(0.2, 5.0)
            at(rng.uniform(0, faults.duration), partial(self._crash, index, down))
        for _ in range(faults.manager_restarts):
            down = rng.uniform(0.2, 2.0)
            at(rng.uniform(0, faults.duration), partial(self._restart_manager, down))

    def run(self) -> SimulationReport:
        started = time.perf_counter()
        scenario = self.scenario
        report = SimulationReport(scenario)
        period = DEFAULT_HEARTBEAT_PERIOD
        for index in range(len(self.nodes)):
            at = self.rng.random() * 0.5
            self._schedule(at, _SCRIPT, payload=partial(self._announce, index))
        # Start-up: recovery, then every node on the first state.
        startup = self.now + 3 * scenario.settings.recovery_window + 10
        if not self.run_until(startup, self._converged, check_every=0.01):
            self._fail("the system did not converge after start-up")
        # Idle: once every node is on the heartbeat period the manager asks for (one period
        # of it), over two of them (one second at least).
        assert self.manager is not None
        status_period = self.manager.status_period
        self.run_until(self.now + status_period)
        idle_from, messages, cpu = self.now, self.counters.messages, self.counters.manager_cpu
        self.run_until(self.now + max(4 * period, 2 * status_period))
        idle = self.now - idle_from
        report.idle_messages_per_second = (self.counters.messages - messages) / idle
        report.idle_manager_cpu_per_second = (self.counters.manager_cpu - cpu) / idle
        # The clean phase, measured.
        messages, cpu, began = self.counters.messages, self.counters.manager_cpu, self.now
        for index in range(scenario.clean_activations):
            self._sync_activation(index)
        count = max(1, scenario.clean_activations)
        report.messages_per_activation = (self.counters.messages - messages) / count
        report.manager_cpu_per_activation = (self.counters.manager_cpu - cpu) / count
        report.activation_time = (self.now - began) / count
        # The fault phase.
        self._faulty = True
        self._script_faults()
        self.run_until(self.now + scenario.faults.duration)
        # The heal: no more faults; the scripted restarts still come (at most 5 s).
        self._faulty = False
        self._cut.clear()
        self.run_until(self.now + 5.0)
        if self.manager is None:
            self.manager = self._start_manager(self.state_file)
        healed = self.now
        if not self.run_until(healed + scenario.converge_within, self._converged, 0.01):
            manager = self.manager
            lagging = [
                n.name for n in self.nodes if n.protocol.applied_epoch != manager.state.epoch
            ]
            self._fail(
                f"no convergence {scenario.converge_within:g} s after the heal: manager at "
                f"epoch {manager.state.epoch}, {len(manager.live_nodes)} of {len(self.nodes)} "
                f"live, lagging {lagging[:5]}"
            )
        report.time_to_converge = self.now - healed
        # Everything asked of the manager that is still running is answered by now.
        # (the fault phase's timeouts are 3 s at most; an atomic one waits twice).
        self.run_until(self.now + 7.0, self._answered, check_every=0.05)
        self._sync_activation(scenario.clean_activations)
        report.status_period = self.manager.status_period
        report.liveness_bound = self.manager.liveness_bound(self.now)
        report.detection_time = self._detection_time()
        for request, asked in self.commands.items():
            if asked.answer is None and asked.manager_generation == self.manager_generation:
                self._fail(f"request {request} ({asked.command}) was never answered")
        report.commands = len(self.commands)
        report.answers = sum(asked.answer is not None for asked in self.commands.values())
        report.aborted_atomic = len(self.invariants.aborted)
        report.messages = self.counters.messages
        report.events = self._events
        report.wall_time = time.perf_counter() - started
        report.trace = self._trace.hexdigest()[:16]
        return report

    def _detection_time(self, count: int = 3) -> float:
        """Crash `count` nodes (for good, on a clean link) and return the longest time until
        the manager dropped one: its liveness bound less the time since the node's last
        heartbeat, plus up to one manager tick."""
        chosen = self.rng.sample(range(len(self.nodes)), min(count, len(self.nodes)))
        names = {self.nodes[index].name for index in chosen}
        for index in chosen:
            self.nodes[index].alive = False
        crashed, self.dropped = self.now, {}
        assert self.manager is not None
        limit = self.now + 2 * self.manager.liveness_bound(self.now) + 1.0
        if not self.run_until(limit, lambda: names <= self.dropped.keys(), check_every=0.01):
            self._fail(f"crashed nodes {sorted(names - self.dropped.keys())} never dropped")
        return max(self.dropped[name] for name in names) - crashed

    def _answered(self) -> bool:
        generation = self.manager_generation
        return all(
            asked.answer is not None or asked.manager_generation != generation
            for asked in self.commands.values()
        )

    def _announce(self, index: int) -> None:
        node = self.nodes[index]
        self._run_participant(index, node.protocol.announce(self.now))
        self._wake(index, self.now + self.rng.random() * node.protocol.heartbeat_period)


def simulate(scenario: Scenario) -> SimulationReport:
    """Run one scenario; raises `InvariantViolation` naming the seed if a guarantee broke."""
    return Simulation(scenario).run()


def sweep(
    seeds: Sequence[int], participants: int, faults: Faults = Faults()
) -> list[SimulationReport]:
    return [simulate(Scenario(participants, seed, faults=faults)) for seed in seeds]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m contextros.protocol.simulation", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--seed", type=int, default=0, help="the run to replay")
    parser.add_argument("--seeds", type=int, default=1, help="run this many seeds from --seed")
    parser.add_argument("--participants", type=int, default=100)
    parser.add_argument("--loss", type=float, default=Faults.loss)
    parser.add_argument("--duplication", type=float, default=Faults.duplication)
    parser.add_argument("--crashes", type=int, default=Faults.crashes)
    parser.add_argument("--partitions", type=int, default=Faults.partitions)
    parser.add_argument("--manager-restarts", type=int, default=Faults.manager_restarts)
    add_check_all_option(parser)
    args = parser.parse_args(argv)
    faults = Faults(
        loss=args.loss,
        duplication=args.duplication,
        crashes=args.crashes,
        partitions=args.partitions,
        manager_restarts=args.manager_restarts,
    )
    failed = 0
    for seed in range(args.seed, args.seed + args.seeds):
        try:
            checked = checked_invariants(args.check_all)
            report = simulate(Scenario(args.participants, seed, faults=faults, checked=checked))
        except InvariantViolation as violation:
            print(f"FAILED {violation}", file=sys.stderr)
            failed += 1
            continue
        print(
            f"seed {seed}: {args.participants} participants, {report.commands} commands "
            f"({report.answers} answered, {report.aborted_atomic} atomic aborted), "
            f"{report.messages_per_activation:.0f} messages and "
            f"{report.manager_cpu_per_activation * 1e3:.2f} ms manager CPU per sync "
            f"activation, converged {report.time_to_converge:.2f} s after the heal; "
            f"heartbeat period {report.status_period:.2f} s, a crashed node dropped after "
            f"{report.detection_time:.2f} s (bound {report.liveness_bound:.1f} s); "
            f"{report.events} events in {report.wall_time:.1f} s; trace {report.trace}"
        )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
