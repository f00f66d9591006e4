"""The participants' own cost per synchronous activation: rclpy's executor against `WaitLoop`
(`spin_nodes(nodes, lean=True)`), one participant per node (issue 16).

Set-up as in section manager_cost: the manager, N context nodes with a participant each in
8 worker processes, and a caller sending back-to-back synchronous activations. Two such
systems run in two ROS domains, one whose workers spin with rclpy's
`SingleThreadedExecutor` (the default) and one whose workers spin lean, with the rounds of
the two interleaved (blocks of 10), so both see the same machine; while one system is
measured, every process of the other is stopped (SIGSTOP; the manager's liveness timeout
is longer than a block, and all of a system stops at once). Measured: the manager's
`elapsed`, and the CPU time (user + system, from /proc) of all worker processes per
activation, less their idle rate (heartbeats) measured just before each block.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from benchmarks.manager_cost import BLOCK, _System, cost_row

NODE_COUNTS = (16, 64)
SETTLE = 1.0  # after the other system is paused and this one continued
ROUNDS = 40
DOMAINS = {"rclpy executor": 85, "lean spin": 86}
LABELS = {"rclpy executor": "executor", "lean spin": "lean"}  # in node names


def run(node_counts: tuple[int, ...] = NODE_COUNTS, rounds: int = ROUNDS) -> list[dict[str, Any]]:
    rows = []
    for count in node_counts:
        print(f"  participant cost: {count} participants", flush=True)
        systems: dict[str, _System] = {}
        try:
            for label, domain in DOMAINS.items():
                lean = label == "lean spin"
                systems[label] = _System(LABELS[label], None, count, lean=lean, domain=domain)
            samples: dict[str, list[float]] = {label: [] for label in systems}
            cpu: dict[str, list[float]] = {label: [] for label in systems}
            for index in range(math.ceil(rounds / BLOCK)):
                order = list(systems) if index % 2 == 0 else list(reversed(systems))
                for label in order:
                    system = systems[label]
                    for other in systems.values():
                        other.pause(other is not system)
                    time.sleep(SETTLE)
                    pids = [worker.pid for worker in system.workers]
                    elapsed, spent = system.block_of(pids, BLOCK)
                    samples[label] += [e for e in elapsed if not math.isnan(e)]
                    cpu[label].append(spent)
        finally:
            for system in systems.values():
                system.close()
        for label in systems:
            rows.append({"spin": label, **cost_row(samples[label], cpu[label], count, rounds)})
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| workers spin with | participants | sync activation, median | p90 | lost "
        "| workers' CPU / activation | per participant | load average |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {row['spin']} | {row['participants']} | {row['median_ms']:.1f} ms "
            f"| {row['p90_ms']:.1f} ms | {row['lost']} | {row['cpu_ms']:.1f} ms "
            f"| {row['cpu_per_participant_ms']:.3f} ms | {row['load']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="the participants' CPU per activation")
    parser.add_argument("--nodes", type=int, nargs="+", default=list(NODE_COUNTS))
    parser.add_argument("--rounds", type=int, default=ROUNDS)
    args = parser.parse_args(argv)
    print(markdown(run(tuple(args.nodes), args.rounds)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
