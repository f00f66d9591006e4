"""Time for a layer activation to reach every node, vs the number of nodes (the paper's Fig. 9).

Set-up, for each N: the Layer manager (`contextros manager`) in its own process; N context
nodes, at most 8 per process (N <= 8: one process; N = 64: 8 processes of 8), each
following the manager and implementing the cleaner's Indoor/Outdoor layers
(`examples/cleaner/location.layers`); this process is the caller. Every node also has a
`location` parameter, validated and applied by a callback, so that the same nodes serve the
plain-ROS baselines. Rounds alternate the series below; each switches Indoor <-> Outdoor.

- asynchronous: the command returns once the state is published; measured from the state's
  publication (its stamp) until the last node applied it (the node's own clock at apply).
- synchronous: measured by the manager, from receiving the command until it holds every
  node's acknowledgement (`elapsed` of the reply); the caller's round trip is shown too.
- atomic: the same with `atomic=True` (every participant votes on the proposed state, then
  the manager commits it and waits for every acknowledgement), measured by the manager.
- parameter, one by one / all in parallel: what a ROS developer would otherwise do: the
  caller sets the parameter on every node through its `set_parameters` service, waiting
  for each reply before the next call, or sending all calls at once; until every reply.
- The context nodes of a process share one participant (`ContextNode`'s default): the
  layer configuration is per process (the COP core's decisive activation is
  process-wide), so when it applies a state every node of its process has the new layers
  at that instant, and the manager waits for one acknowledgement per process.
  "..., one participant per node" rows: the same with `share_participant=False`, so that
  every node applies and acknowledges on its own. Same nodes, same parameter services.
- floor: one topic round trip between two processes (the caller's ping, an echo node in
  the first worker process, its pong), measured in the same rounds, under the same load.

Between two measurements the caller pauses 5 ms, as a robot's context switches are sparse:
an idle process takes longer to wake than one kept busy by back-to-back messages (here a
back-to-back topic round trip took about half the time of a paused one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from contextros import LayerError

if TYPE_CHECKING:
    from contextros.protocol import LayerState

NODE_COUNTS = (1, 2, 4, 8, 12, 16, 32, 64)
NODES_PER_PROCESS = 8
ROUNDS = 40  # per series and N
BENCH_DOMAIN_ID = 78
FLOOR = "floor: topic round trip"
MODES = (
    "asynchronous",
    "synchronous",
    "atomic",
    "parameter, one by one",
    "parameter, parallel",
    FLOOR,
)
PER_NODE = ", one participant per node"
# The workers spin with WaitLoop (spin_nodes(nodes, lean=True), the default since issue 26);
# the other series with rclpy's executor (lean=False, as rclpy.spin(node) spins).
LEAN = ", lean spin"
SERIES = (
    "asynchronous",
    "synchronous",
    "synchronous, caller",
    "atomic",
    "asynchronous" + PER_NODE,
    "synchronous" + PER_NODE,
    "asynchronous" + PER_NODE + LEAN,
    "synchronous" + PER_NODE + LEAN,
    *MODES[3:],
)
PINGS_PER_ROUND = 5
PAPER_FIG9 = (
    "asynchronous activation time for 1 to 12 nodes, growing with N, on an axis from 0 to 0.1 s"
    " (the text gives no values; ROS 1, C++, in VirtualBox on a MacBook Air)"
)
# Why a target can be missed: the reasons found when measuring (see the per-node costs above).
WHY_MISSED = {
    "atomic": (
        "An atomic activation is two rounds (proposal out, every vote back; then the state out,"
        " every acknowledgement back), each as costly as a synchronous activation's one, plus"
        " the manager's 50 ms tick that repeats the proposal only if a vote is late."
    ),
    "parallel": (
        "With one participant per node, a synchronous activation costs per node one state"
        " callback and one status message (handled by the node's and the manager's rclpy"
        " executors), a parallel parameter call one request and one response: the same number"
        " of Python callbacks, which dominate here (applying the layers themselves takes about"
        " 40 µs per node). The broadcast saves the caller's N requests, not the nodes' and the"
        " manager's work; sharing one participant per process (the default) is what saves"
        " it."
    ),
    "participants": (
        "With one participant per node, 64 participants in 8 processes apply each state and"
        " answer it on 2 cores: each process takes, applies and answers its 8 states one"
        " after the other in rclpy's executor (about half of such a process's Python time"
        " is the executor's own, in a py-spy profile of issue 16), while the manager's part"
        " per participant is under 0.1 ms (section manager_cost). The time is the"
        " participants' processes waiting for a core. Spun by `WaitLoop` (the lean-spin"
        " series, `spin_nodes`' default since issue 26) the executor's share goes (23-31 ms"
        " instead of 36-41 ms at N=64 in issue 16's fourth session); what is left, in a"
        " py-spy profile of those workers, is half waiting on each process's wait set (8"
        " nodes with their parameter services and QoS event handlers, about 100 entities)"
        " and the per-participant take, apply and status. 64 C++ nodes in 64 processes took"
        " 24 ms on the same 2 cores (section cpp_activation)."
    ),
    "floor": (
        "A synchronous activation is four messages (command, state, acknowledgement, answer)"
        " against the floor's two, plus work the floor has not: the"
        " manager's handling of the command and of the acknowledgement, and the node's apply"
        " and status message, each a Python callback of 0.1-0.3 ms in rclpy's executor; on"
        " this shared machine the ratio moved between about 1.2 and 1.7 from run to run (issue"
        " 16: four runs, two of the code before)."
    ),
    "growth": (
        "The time grows with the number of participants and processes: each participant runs"
        " its own state callback and sends its own acknowledgement, the manager handles each"
        " (about 0.5-0.8 ms of CPU per participant in all), and from N=16 on there are more"
        " worker processes than the machine's two cores, shared with other jobs (the floor"
        " row shows the load at each N). With one participant per process (the default)"
        " the growth is that of the processes alone. The paper's prototype grew with N as"
        " well."
    ),
}
LOCATION_LAYERS = Path(__file__).resolve().parent.parent / "examples/cleaner/location.layers"
CONTEXTS = ("Indoor", "Outdoor")


# -- the worker processes ---------------------------------------------------------------------


def worker(names: list[str], echo: bool, per_node: bool, lean: bool = False) -> None:
    """Host context nodes (and the floor's echo) until interrupted, then print apply times.

    They share one participant (the default), or with `per_node` each has its own; `lean`:
    spun by `WaitLoop` (`spin_nodes(..., lean=True)`) instead of rclpy's executor (else
    `lean=False`: the series stay comparable with the runs before WaitLoop was the default).
    """
    import rclpy
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.node import Node
    from std_msgs.msg import UInt64

    from contextros.language import load
    from contextros.ros import ContextNode, spin_nodes

    location = load(LOCATION_LAYERS)
    applied: dict[str, dict[int, float]] = {name: {} for name in names}

    def check(parameters: list[Any]) -> Any:
        for parameter in parameters:
            if parameter.name == "location" and parameter.value not in CONTEXTS:
                return SetParametersResult(successful=False, reason="unknown location")
        return SetParametersResult(successful=True)

    # Without rclpy's own signal handler, Ctrl-C reaches spin_nodes as KeyboardInterrupt while
    # the context is still up, so every node can still tell the manager it leaves.
    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)

    def recorder(log: dict[int, float]) -> Callable[[LayerState], None]:
        def record(state: LayerState) -> None:
            log[state.epoch] = time.time()

        return record

    nodes: list[Node] = []
    for name in names:
        node = ContextNode(name, layers=location.__layers__, share_participant=not per_node)
        node.context_participant.add_listener(recorder(applied[name]))
        node.add_on_set_parameters_callback(check)
        node.declare_parameter("location", "Indoor")
        nodes.append(node)
    if echo:
        echo_node = rclpy.create_node("bench_echo")
        pong = echo_node.create_publisher(UInt64, "bench/pong", 10)
        echo_node.create_subscription(UInt64, "bench/ping", pong.publish, 10)
        nodes.append(echo_node)
    print("ready", flush=True)
    spin_nodes(nodes, lean=lean)
    print(json.dumps({"applied": applied}), flush=True)
    rclpy.try_shutdown()


# -- the caller -------------------------------------------------------------------------------


class Caller:
    """This process's node: activation client, parameter clients, state/status listener."""

    def __init__(self) -> None:
        import rclpy
        from contextros_interfaces.msg import LayerState
        from std_msgs.msg import UInt64

        from contextros.ros import STATE_QOS, STATE_TOPIC, LayerClient

        self.rclpy = rclpy
        self.node = rclpy.create_node("bench_caller")
        self.client = LayerClient(self.node, requester="bench")
        self.published: dict[int, float] = {}  # epoch -> stamp of its state
        self.pongs: dict[int, float] = {}
        self.sequence = 0  # of the pings; a pong is matched to its ping by it
        self.node.create_subscription(LayerState, STATE_TOPIC, self.on_state, STATE_QOS)
        self.ping = self.node.create_publisher(UInt64, "bench/ping", 10)
        self.node.create_subscription(UInt64, "bench/pong", self.on_pong, 10)
        self.parameter_clients: list[Any] = []

    def on_state(self, msg: Any) -> None:
        self.published[msg.epoch] = msg.stamp.sec + msg.stamp.nanosec * 1e-9

    def on_pong(self, msg: Any) -> None:
        self.pongs[msg.data] = time.perf_counter()

    def spin_until(self, condition: Any, timeout: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.rclpy.spin_once(self.node, timeout_sec=0.01)
        return True

    def wait_for_nodes(
        self, names: list[str], participants: list[str], timeout: float = 60.0
    ) -> None:
        from rcl_interfaces.srv import SetParameters

        self.client.wait_for_manager(timeout)
        wanted = set(participants)
        deadline = time.monotonic() + timeout
        # Exactly these: the nodes of the previous N must have left, or they would be waited for.
        while wanted != {p.node.lstrip("/") for p in self.client.query().participants}:
            if time.monotonic() > deadline:
                raise TimeoutError(f"not all {len(wanted)} participants joined in {timeout:g} s")
            time.sleep(0.2)
        self.parameter_clients = [
            self.node.create_client(SetParameters, f"/{name}/set_parameters") for name in names
        ]
        for client in self.parameter_clients:
            if not client.wait_for_service(timeout_sec=max(0.1, deadline - time.monotonic())):
                raise TimeoutError(f"no parameter service {client.srv_name}")
        self.wait_until_applied(self.client.query().epoch, len(participants))

    def wait_until_applied(self, epoch: int, count: int) -> None:
        """Until the manager knows every node applied `epoch`: asked sparingly, as the caller
        must not load the machine while the nodes work (it does not follow their statuses)."""
        time.sleep(0.002 + 0.001 * count)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            participants = self.client.query().participants
            if len(participants) >= count and all(p.applied_epoch >= epoch for p in participants):
                return
            time.sleep(0.005)
        raise TimeoutError(f"epoch {epoch} not applied by all {count} nodes within 10 s")

    def active_context(self) -> str:
        """The context the manager has active (Indoor when none yet: the next switch is Outdoor)."""
        return "Outdoor" if list(self.client.query().active_layers) == ["Outdoor"] else "Indoor"

    def activate(self, context: str, synchronous: bool, atomic: bool = False) -> tuple[Any, float]:
        other = CONTEXTS[1 - CONTEXTS.index(context)]
        started = time.perf_counter()
        result = self.client.request(
            [context], [other], synchronous=synchronous, timeout=5.0, atomic=atomic
        )
        round_trip = time.perf_counter() - started
        if not result.success:
            raise RuntimeError(f"activation of {context} failed: {result.message}")
        return result, round_trip

    def set_parameters(self, context: str, parallel: bool) -> float:
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters

        value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=context)
        request = SetParameters.Request(parameters=[Parameter(name="location", value=value)])
        started = time.perf_counter()
        if parallel:
            futures = [client.call_async(request) for client in self.parameter_clients]
            self.spin_until(lambda: all(f.done() for f in futures))
        else:
            futures = []
            for client in self.parameter_clients:
                futures.append(client.call_async(request))
                self.spin_until(futures[-1].done)
        elapsed = time.perf_counter() - started
        if not all(f.done() and f.result().results[0].successful for f in futures):
            raise RuntimeError(f"setting the location parameter to {context} failed")
        return elapsed

    def round_trip(self) -> float:
        from std_msgs.msg import UInt64

        self.sequence += 1
        sequence = self.sequence
        started = time.perf_counter()
        self.ping.publish(UInt64(data=sequence))
        if not self.spin_until(lambda: sequence in self.pongs, timeout=2.0):
            return math.nan
        return self.pongs[sequence] - started

    def close(self) -> None:
        self.node.destroy_node()


def _start_workers(
    launch: Any, count: int, per_process: int, per_node: bool, lean: bool = False
) -> tuple[list[str], list[str]]:
    """Start the workers; return the names of all nodes and of the participants among them."""
    processes = math.ceil(count / per_process)
    # Names unique per run: a node of the previous run still leaving cannot be mistaken for one.
    variant = ("l" if lean else "p") if per_node else "s"
    names = [f"bench_{count}{variant}_n{index:02d}" for index in range(count)]
    participants = []
    for process in range(processes):
        own = names[process::processes]
        participants += own if per_node else own[:1]
        options = ["--echo"] if process == 0 else []
        options += ["--per-node"] if per_node else []
        options += ["--lean"] if lean else []
        launch.start_module(f"worker{process}", "benchmarks.activation", "worker", *own, *options)
    return names, participants


def _wait_for_lines(launch: Any, text: str, count: int, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    seen = 0
    while seen < count:
        line = launch.next_line(deadline - time.monotonic())
        if line is None:
            raise TimeoutError(f"only {seen} of {count} processes printed {text!r}")
        if line.text == text:
            seen += 1
        elif "Error" in line.text or "Traceback" in line.text:
            print(f"  {line.process}: {line.text}", file=sys.stderr)


def _collect_apply_times(launch: Any) -> dict[str, dict[int, float]]:
    for name in list(launch.processes):
        if name.startswith("worker"):
            launch.stop(name)
    applied: dict[str, dict[int, float]] = {}
    while (line := launch.next_line(0.5)) is not None:
        if line.text.startswith('{"applied"'):
            for node, times in json.loads(line.text)["applied"].items():
                applied[node] = {int(epoch): t for epoch, t in times.items()}
    return applied


def measure(
    count: int,
    caller: Caller,
    launch: Any,
    rounds: int,
    per_process: int,
    per_node: bool,
    lean: bool = False,
) -> dict[str, list[float]]:
    """Seconds per activation, per series, for `count` nodes (workers started and stopped).

    With `per_node`, only the two activation modes are measured (the rest does not change).
    """
    names, participants = _start_workers(launch, count, per_process, per_node, lean)
    _wait_for_lines(launch, "ready", math.ceil(count / per_process))
    caller.wait_for_nodes(names, participants)
    caller.spin_until(lambda: caller.ping.get_subscription_count() > 0)
    for _ in range(20):  # warm the echo path up; its late replies cannot match later pings
        caller.round_trip()
    times: dict[str, list[float]] = {series: [] for series in SERIES}
    async_epochs: list[int] = []
    active = caller.active_context()
    modes = MODES[:2] if per_node else MODES
    for index in range(rounds):
        for mode in modes if index % 2 else reversed(modes):
            target = CONTEXTS[1 - CONTEXTS.index(active)]
            try:
                if mode == "asynchronous":
                    result, _ = caller.activate(target, synchronous=False)
                    async_epochs.append(result.epoch)
                    caller.wait_until_applied(result.epoch, len(participants))
                    active = target
                elif mode == "synchronous":
                    result, round_trip = caller.activate(target, synchronous=True)
                    times["synchronous"].append(result.elapsed)
                    times["synchronous, caller"].append(round_trip)
                    active = target
                elif mode == "atomic":
                    result, _ = caller.activate(target, synchronous=False, atomic=True)
                    times["atomic"].append(result.elapsed)
                    active = target
                elif mode == FLOOR:
                    for _ in range(PINGS_PER_ROUND):
                        times[FLOOR].append(caller.round_trip())
                        time.sleep(0.005)
                else:
                    parallel = "parallel" in mode
                    times[mode].append(caller.set_parameters(target, parallel=parallel))
            except (RuntimeError, TimeoutError, LayerError) as error:
                # A lost sample, reported as lost; the manager's state decides what is active.
                print(f"  {count} nodes, {mode}: {error}", file=sys.stderr, flush=True)
                active = (
                    "Outdoor"
                    if list(caller.client.query().active_layers) == ["Outdoor"]
                    else "Indoor"
                )
            time.sleep(0.005)  # a pause between measurements, as between real context switches
    applied = _collect_apply_times(launch)
    for epoch in async_epochs:
        stamps = [applied.get(name, {}).get(epoch) for name in names]
        published = caller.published.get(epoch)
        if published is None or None in stamps:
            continue  # a lost sample (reported as lost), never a guessed one
        times["asynchronous"].append(max(s for s in stamps if s is not None) - published)
    if per_node:
        return {mode + PER_NODE + (LEAN if lean else ""): times[mode] for mode in modes}
    return times


def run(
    node_counts: tuple[int, ...] = NODE_COUNTS,
    rounds: int = ROUNDS,
    per_process: int = NODES_PER_PROCESS,
) -> list[dict[str, Any]]:
    import rclpy
    from examples.launch import Launch

    domain = int(os.environ.get("CONTEXTROS_BENCH_DOMAIN_ID", BENCH_DOMAIN_ID))
    rows: list[dict[str, Any]] = []
    load_before = os.getloadavg()[0]
    with Launch(domain, grace=5.0) as launch:
        launch.start_module("manager", "contextros", "manager", "--recovery-window", "0.3")
        rclpy.init(domain_id=domain)
        caller = Caller()
        try:
            for count in node_counts:
                print(f"  activation: {count} nodes", flush=True)
                times: dict[str, list[float]] = {}
                for per_node, lean in ((False, False), (True, False), (True, True)):
                    try:
                        times |= measure(count, caller, launch, rounds, per_process, per_node, lean)
                    except (RuntimeError, TimeoutError, LayerError) as error:
                        # Not measured (reported as lost), rather than no report at all.
                        print(f"  {count} nodes: {error}", file=sys.stderr, flush=True)
                        _collect_apply_times(launch)  # stops the workers
                for series in SERIES:
                    attempts = rounds * (PINGS_PER_ROUND if series == FLOOR else 1)
                    row = _row(series, count, times.get(series, []), attempts, rounds)
                    rows.append(row | {"per_process": per_process})
        finally:
            caller.close()
            rclpy.try_shutdown()
    load = {"load_before": load_before, "load_after": os.getloadavg()[0]}
    return [row | load for row in rows]


def _row(
    series: str, count: int, samples: list[float], attempted: int, rounds: int
) -> dict[str, Any]:
    ordered = sorted(s for s in samples if not math.isnan(s))
    return {
        "series": series,
        "nodes": count,
        "rounds": rounds,
        "median_ms": statistics.median(ordered) * 1000 if ordered else math.nan,
        "p90_ms": ordered[int(0.9 * (len(ordered) - 1))] * 1000 if ordered else math.nan,
        "samples": len(ordered),
        "lost": attempted - len(ordered),
    }


# -- the report -------------------------------------------------------------------------------


def _median(rows: list[dict[str, Any]], series: str, nodes: int) -> float:
    for row in rows:
        if row["series"] == series and row["nodes"] == nodes:
            return float(row["median_ms"])
    return math.nan


def markdown(rows: list[dict[str, Any]]) -> str:
    counts = sorted({row["nodes"] for row in rows})
    if not counts:
        return "Not measured."
    floor = _median(rows, FLOOR, counts[0])
    header = "| series: median ms (p90) | " + " | ".join(f"N={n}" for n in counts)
    per_process = rows[0]["per_process"]
    processes = " | ".join(str(math.ceil(n / per_process)) for n in counts)
    lines = [
        f"Layout: the manager, the caller, and N nodes in ceil(N/{per_process}) worker "
        f"processes of up to {per_process} nodes (one single-threaded executor each); "
        f"{rows[0]['rounds']} measurements per series and N "
        f"({rows[0]['rounds'] * PINGS_PER_ROUND} for the floor). Load average (1 min) of the"
        f" machine at the start and end of this benchmark: {rows[0]['load_before']:.1f} and"
        f" {rows[0]['load_after']:.1f}, on {os.cpu_count()} cores shared with other jobs.",
        "",
        header + " |",
        "|---|" + "---:|" * len(counts),
        f"| worker processes | {processes} |",
    ]
    for series in SERIES:
        cells = []
        for count in counts:
            row = next(r for r in rows if r["series"] == series and r["nodes"] == count)
            lost = f", {row['lost']} lost" if row["lost"] else ""
            cells.append(f"{row['median_ms']:.2f} ({row['p90_ms']:.2f}{lost})")
        lines.append(f"| {series} | " + " | ".join(cells) + " |")
    sync_64, sync_1 = _median(rows, "synchronous", 64), _median(rows, "synchronous", 1)
    async_64, async_1 = _median(rows, "asynchronous", 64), _median(rows, "asynchronous", 1)
    per_node_64 = _median(rows, "synchronous" + PER_NODE, 64)
    per_node_1 = _median(rows, "synchronous" + PER_NODE, 1)
    per_node_async_64 = _median(rows, "asynchronous" + PER_NODE, 64)
    per_node_async_1 = _median(rows, "asynchronous" + PER_NODE, 1)
    lean_64 = _median(rows, "synchronous" + PER_NODE + LEAN, 64)
    lean_1 = _median(rows, "synchronous" + PER_NODE + LEAN, 1)
    parallel_64 = _median(rows, "parameter, parallel", 64)
    atomic_64 = _median(rows, "atomic", 64)
    checks = [
        ("atomic at N=64 / synchronous at N=64", atomic_64 / sync_64, 2.0, "atomic"),
        (
            "synchronous at N=64 / parameter, parallel at N=64",
            sync_64 / parallel_64,
            0.5,
            "parallel",
        ),
        ("synchronous at N=1 / floor at N=1 (issue 16)", sync_1 / floor, 1.5, "floor"),
        ("synchronous N=64 / N=1", sync_64 / sync_1, 8.0, "growth"),
        ("asynchronous N=64 / N=1", async_64 / async_1, 8.0, "growth"),
        (
            "synchronous, one participant per node, at N=64 / parameter, parallel at N=64 "
            "(issue 16)",
            per_node_64 / parallel_64,
            0.3,
            "parallel",
        ),
        (
            "synchronous, one participant per node, at N=64, median ms (issue 16)",
            per_node_64,
            15.0,
            "participants",
        ),
        (
            "synchronous, one participant per node, N=64 / N=1 (issue 16)",
            per_node_64 / per_node_1,
            4.0,
            "participants",
        ),
        (
            "synchronous, one participant per node, lean spin, at N=64 / parameter, parallel "
            "at N=64 (issue 16)",
            lean_64 / parallel_64,
            0.3,
            "parallel",
        ),
        (
            "synchronous, one participant per node, lean spin, at N=64, median ms (issue 16)",
            lean_64,
            15.0,
            "participants",
        ),
        (
            "synchronous, one participant per node, lean spin, N=64 / N=1 (issue 16)",
            lean_64 / lean_1,
            4.0,
            "participants",
        ),
        (
            "asynchronous, one participant per node, N=64 / N=1",
            per_node_async_64 / per_node_async_1,
            8.0,
            "growth",
        ),
    ]
    lines += ["", "| target | measured | target | verdict |", "|---|---:|---:|---|"]
    missed: list[str] = []
    for name, value, target, why in checks:
        verdict = "not measured" if math.isnan(value) else "met" if value <= target else "MISSED"
        lines.append(f"| {name} | {value:.2f} | <= {target:g} | {verdict} |")
        if verdict == "MISSED" and why not in missed:
            missed.append(why)
    lines += ["", f"Paper, Fig. 9: {PAPER_FIG9}."]
    if missed:
        lines += ["", "Why targets were missed:", ""]
        lines += [f"- {WHY_MISSED[why]}" for why in missed]
    return "\n".join(lines)


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7, 4.5))
    for series in SERIES:
        points = sorted((r["nodes"], r["median_ms"]) for r in rows if r["series"] == series)
        style = ":" if series == FLOOR else "--" if PER_NODE in series else "-"
        axes.plot([n for n, _ in points], [m for _, m in points], style, marker="o", label=series)
    axes.set_xscale("log", base=2)
    axes.set_yscale("log")
    axes.set_xticks(list(NODE_COUNTS), [str(n) for n in NODE_COUNTS])
    axes.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    axes.set_xlabel("nodes")
    axes.set_ylabel("time until every node has the new layers [ms] (median)")
    axes.set_title("Layer activation time vs number of nodes")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def main(argv: list[str]) -> int:
    """`worker NAME... [--echo]` hosts nodes; else a (quick) run: `--nodes 1 8 --rounds 10`."""
    if argv[:1] == ["worker"]:
        parser = argparse.ArgumentParser(description="activation benchmark: a worker process")
        parser.add_argument("names", nargs="*")
        parser.add_argument("--echo", action="store_true")
        parser.add_argument("--per-node", action="store_true")
        parser.add_argument("--lean", action="store_true")
        worker_args = parser.parse_args(argv[1:])
        worker(worker_args.names, worker_args.echo, worker_args.per_node, worker_args.lean)
        return 0
    parser = argparse.ArgumentParser(description="activation benchmark")
    parser.add_argument("--nodes", type=int, nargs="+", default=list(NODE_COUNTS))
    parser.add_argument("--rounds", type=int, default=ROUNDS)
    parser.add_argument("--per-process", type=int, default=NODES_PER_PROCESS)
    args = parser.parse_args(argv)
    rows = run(tuple(args.nodes), args.rounds, args.per_process)
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
