"""Measuring how long a system-wide layer switch takes, for benchmarks and users' own checks.

`python -m contextros.ros.latency --nodes 64 --processes 4` starts a Layer manager and 4
processes hosting 16 context nodes each (one executor each), then times synchronous activations from
this process: the client's round trip, from sending the command to the answer that every
node has applied the new state. `swarm` runs only the context nodes (N nodes in one process).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import rclpy
from rclpy.node import Node

from contextros.cli.ros_arguments import split_ros_arguments
from contextros.core import Layer
from contextros.protocol import ManagerError
from contextros.ros.client import LayerClient
from contextros.ros.participant import ContextNode
from contextros.ros.spinning import spin_nodes

BENCH_LAYERS = ("BenchA", "BenchB")


@dataclass(frozen=True)
class LatencyReport:
    nodes: int
    rounds: int
    round_trips: tuple[float, ...]  # seconds, client side
    manager_elapsed: tuple[float, ...]  # seconds, as the manager measured them

    def summary(self) -> dict[str, float | int]:
        ordered = sorted(self.round_trips)
        return {
            "nodes": self.nodes,
            "rounds": self.rounds,
            "median_ms": statistics.median(ordered) * 1000,
            "p90_ms": ordered[int(0.9 * (len(ordered) - 1))] * 1000,
            "p99_ms": ordered[int(0.99 * (len(ordered) - 1))] * 1000,
            "max_ms": ordered[-1] * 1000,
            "manager_median_ms": statistics.median(self.manager_elapsed) * 1000,
        }


def context_node_swarm(
    count: int, layers: Sequence[str] = BENCH_LAYERS, first: int = 0
) -> list[ContextNode]:
    """`count` context nodes (ctx_<first>...) implementing `layers`, for one executor.

    Each node has a participant of its own, so that the protocol is measured per
    participant (context nodes of one process share one by default). Without parameter
    services: rclpy's executor walks every entity of every node on each wake-up, and six
    services per node would dominate the measurement.
    """
    for name in layers:
        Layer(name, group="bench")
    return [
        ContextNode(
            f"ctx_{index}",
            layers=list(layers),
            share_participant=False,
            start_parameter_services=False,
        )
        for index in range(first, first + count)
    ]


def measure_activation_latency(
    client: LayerClient,
    rounds: int,
    expected_nodes: int,
    layers: Sequence[str] = BENCH_LAYERS,
    warmup: int = 5,
    timeout: float = 10.0,
) -> LatencyReport:
    """Time `rounds` synchronous activations, alternating between `layers` (one group, so
    every command really changes the state). Fails if any is not acknowledged by all."""
    trips: list[float] = []
    elapsed: list[float] = []
    for index in range(warmup + rounds):
        layer = layers[index % len(layers)]
        started = time.perf_counter()
        result = client.request([layer], synchronous=True, timeout=timeout)
        trip = time.perf_counter() - started
        if not result.success or len(result.acknowledged) < expected_nodes:
            raise ManagerError(
                f"activation {index} acknowledged by {len(result.acknowledged)} of "
                f"{expected_nodes} nodes: {result.message}"
            )
        if index >= warmup:
            trips.append(trip)
            elapsed.append(result.elapsed)
    return LatencyReport(expected_nodes, rounds, tuple(trips), tuple(elapsed))


def _wait_for_participants(client: LayerClient, count: int, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            registry = client.query(timeout=1.0)
        except ManagerError:
            continue
        if registry.epoch >= 1 and len(registry.participants) >= count:
            return
        time.sleep(0.1)
    raise ManagerError(f"fewer than {count} participants registered within {timeout:g} s")


def _run_swarm(count: int, first: int, ros_arguments: Sequence[str]) -> int:
    rclpy.init(args=["latency", *ros_arguments])
    nodes = context_node_swarm(count, first=first)
    print(json.dumps({"event": "ready", "nodes": count}), flush=True)
    spin_nodes(nodes)
    rclpy.try_shutdown()
    return 0


def _run_measurement(count: int, rounds: int, processes: int, ros_arguments: Sequence[str]) -> int:
    env = dict(os.environ)
    env.pop("RMW_IMPLEMENTATION", None)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    children = [
        subprocess.Popen([sys.executable, "-m", "contextros", "manager", *ros_arguments], env=env)
    ]
    share, extra = divmod(count, processes)
    first = 0
    for index in range(processes):
        size = share + (1 if index < extra else 0)
        argv = ["swarm", "--nodes", str(size), "--first", str(first), *ros_arguments]
        first += size
        children.append(
            subprocess.Popen(
                [sys.executable, "-m", "contextros.ros.latency", *argv],
                env=env,
                stdout=subprocess.DEVNULL,
            )
        )
    rclpy.init(args=["latency", *ros_arguments])
    node = Node("contextros_latency_client")
    try:
        client = LayerClient(node, requester="latency")
        client.wait_for_manager(30.0)
        _wait_for_participants(client, count)
        report = measure_activation_latency(client, rounds, count)
        summary = report.summary() | {"processes": processes}
        print(json.dumps({k: round(v, 3) for k, v in summary.items()}))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        for child in children:
            child.terminate()
        for child in children:
            child.wait(10)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m contextros.ros.latency")
    parser.add_argument("mode", nargs="?", choices=["measure", "swarm"], default="measure")
    parser.add_argument("--nodes", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=100)
    parser.add_argument("--processes", type=int, default=1, help="spread the nodes over these")
    parser.add_argument("--first", type=int, default=0, help=argparse.SUPPRESS)
    # Standard ROS arguments (e.g. `--ros-args -r __ns:=/robot1`) apply to every process.
    own, ros_arguments = split_ros_arguments(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(own)
    if args.mode == "swarm":
        return _run_swarm(args.nodes, args.first, ros_arguments)
    return _run_measurement(args.nodes, args.rounds, max(1, args.processes), ros_arguments)


if __name__ == "__main__":
    sys.exit(main())
