"""The participants' own cost per synchronous activation: rclpy's executor against `WaitLoop`
(`spin_nodes`' default since issue 26), one participant per node (issues 16 and 26).

Set-up as in section manager_cost: the manager, N context nodes with a participant each in
8 worker processes, and a caller sending back-to-back synchronous activations. One such
system per way of spinning (the workers' `spin_nodes(nodes, lean=False)`: rclpy's
`SingleThreadedExecutor`, the way `rclpy.spin(node)` spins; `lean=True`: `WaitLoop`), each
in its own ROS domain, and with `CONTEXTROS_BEFORE=<a source tree>` the same two on that
tree's code (benchmarks/code_before.py). Their rounds are interleaved (blocks of 10), so
all see the same machine; while one system is measured, every process of the others is
stopped (SIGSTOP; the manager's liveness timeout is longer than a block, and all of a
system stops at once). Measured: the manager's `elapsed`, and the CPU time (user + system,
from /proc) of all worker processes per activation, less their idle rate (heartbeats)
measured just before each block.

`--profile PREFIX` first records a worker of each spin with py-spy (native frames too)
during 400 activations of that system alone: PREFIX-<spin>-<N>.txt, collapsed stacks."""

from __future__ import annotations

import argparse
import math
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.code_before import trees_to_compare
from benchmarks.manager_cost import BLOCK, _System, cost_row

NODE_COUNTS = (16, 64)
SETTLE = 1.0  # after the other systems are paused and this one continued
ROUNDS = 40
SPINS = {"rclpy executor": "executor", "lean spin": "lean"}  # label: in node names
FIRST_DOMAIN = 85
TARGET_CPU_PER_PARTICIPANT_MS = 0.1
PROFILE_ROUNDS = 400


def run(
    node_counts: tuple[int, ...] = NODE_COUNTS, rounds: int = ROUNDS, profile: str = ""
) -> list[dict[str, Any]]:
    trees = trees_to_compare()
    rows = []
    for count in node_counts:
        if profile:
            for spin in SPINS:
                _profile(count, spin, f"{profile}-{SPINS[spin]}-{count}.txt")
        print(f"  participant cost: {count} participants", flush=True)
        systems: dict[tuple[str, str], _System] = {}
        try:
            for code, tree in trees.items():
                for spin, name in SPINS.items():
                    label = name + ("b" if tree is not None else "")
                    domain = FIRST_DOMAIN + len(systems)
                    lean = spin == "lean spin"
                    systems[spin, code] = _System(label, tree, count, lean=lean, domain=domain)
            samples: dict[tuple[str, str], list[float]] = {key: [] for key in systems}
            cpu: dict[tuple[str, str], list[float]] = {key: [] for key in systems}
            for index in range(math.ceil(rounds / BLOCK)):
                order = list(systems) if index % 2 == 0 else list(reversed(systems))
                for key in order:
                    system = systems[key]
                    for other in systems.values():
                        other.pause(other is not system)
                    time.sleep(SETTLE)
                    pids = [worker.pid for worker in system.workers]
                    elapsed, spent = system.block_of(pids, BLOCK)
                    samples[key] += [e for e in elapsed if not math.isnan(e)]
                    cpu[key].append(spent)
        finally:
            for system in systems.values():
                system.close()
        for spin, code in systems:
            row = cost_row(samples[spin, code], cpu[spin, code], count, rounds)
            rows.append({"spin": spin, "code": code, **row})
    return rows


def _profile(count: int, spin: str, path: str) -> None:
    """py-spy records the first worker of a system spun so (native frames too), alone on
    the machine, during `PROFILE_ROUNDS` back-to-back activations."""
    system = _System(SPINS[spin] + "p", None, count, lean=spin == "lean spin", domain=84)
    spy = str(Path(sys.executable).parent / "py-spy")
    pid = str(system.workers[0].pid)
    command = [spy, "record", "--pid", pid, "-o", path, "--format", "raw", "--native"]
    recorder = subprocess.Popen([*command, "--rate", "500"])
    try:
        system.block_of([system.workers[0].pid], PROFILE_ROUNDS)
    finally:
        recorder.send_signal(signal.SIGINT)
        recorder.wait()
        system.close()


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| workers spin with | code | participants | sync activation, median | p90 | lost "
        "| workers' CPU / activation | per participant | target <= 0.1 ms | load average |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for row in rows:
        per = row["cpu_per_participant_ms"]
        verdict = "met" if per <= TARGET_CPU_PER_PARTICIPANT_MS else "missed"
        lines.append(
            f"| {row['spin']} | {row['code']} | {row['participants']} "
            f"| {row['median_ms']:.1f} ms | {row['p90_ms']:.1f} ms | {row['lost']} "
            f"| {row['cpu_ms']:.1f} ms | {per:.3f} ms | {verdict} | {row['load']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="the participants' CPU per activation")
    parser.add_argument("--nodes", type=int, nargs="+", default=list(NODE_COUNTS))
    parser.add_argument("--rounds", type=int, default=ROUNDS)
    parser.add_argument(
        "--profile",
        default="",
        help="first, py-spy of a worker of each spin: PREFIX-<spin>-<N>.txt (collapsed stacks)",
    )
    args = parser.parse_args(argv)
    print(markdown(run(tuple(args.nodes), args.rounds, args.profile)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
