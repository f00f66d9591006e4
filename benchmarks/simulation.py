"""The pure protocol at fleet scale, simulated (issue 16): one manager and N participants in
`contextros.protocol.simulation` (no ROS: the protocol's own cost, not rclpy's). Each run:
start-up, 5 back-to-back synchronous activations on a clean link (measured), 10 s of faults
(20% loss, 10% duplication, 1-250 ms delay that reorders, 2 partitions of a tenth of the
nodes, 3 node crashes, 1 manager restart, 12 commands of every kind), then a heal, and at
the end 3 nodes crashed for good. Every guarantee is checked all along (`Invariants`: ok
means none broke). Columns: messages on the wire per synchronous activation; the manager's
CPU per activation (real CPU of this process inside the manager's state machine) and per
participant; the activation's simulated duration (a 0.5-2 ms link); with nothing happening,
messages per second both ways and the manager's CPU share (measured once every node is on
the heartbeat period the manager asks for, over two such periods, one second at least);
that period and the liveness bound (issue 26: the period grows beyond `status_rate`
statuses per second, 250 participants, and the bound with it); the longest time from a
crash to the manager dropping the node; seconds from the heal to every node live and on
the manager's epoch. Replay a row with
`python -m contextros.protocol.simulation --seed 1 --participants N`.

Each size runs in a child process; with `CONTEXTROS_BEFORE=<a source tree>` the same runs
on that tree's code too, in the next child, before or after alternately (issue 26's
before/after: benchmarks/code_before.py).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from benchmarks.code_before import before_environment

SIZES = (10, 100, 1_000, 10_000)
SEED = 1

# What a child runs: one scenario on its tree's code (fields a tree does not have yet: 0).
_CHILD = """
import json, sys
from contextros.protocol.simulation import InvariantViolation, Scenario, simulate
participants, seed = int(sys.argv[1]), int(sys.argv[2])
try:
    report = simulate(Scenario(participants, seed))
except InvariantViolation as violation:
    print(json.dumps({"violation": str(violation).splitlines()[0]}))
    raise SystemExit(0)
fields = ("messages_per_activation", "manager_cpu_per_activation", "activation_time",
          "idle_messages_per_second", "idle_manager_cpu_per_second", "time_to_converge",
          "commands", "wall_time", "status_period", "liveness_bound", "detection_time")
print(json.dumps({name: getattr(report, name, 0) for name in fields}))
"""


def _simulate(participants: int, environment: dict[str, str]) -> dict[str, Any]:
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, str(participants), str(SEED)],
        env=os.environ | environment,
        cwd=Path(__file__).resolve().parent.parent,
        capture_output=True,
        text=True,
        check=True,
    )
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def run(sizes: tuple[int, ...] = SIZES) -> list[dict[str, Any]]:
    before = os.environ.get("CONTEXTROS_BEFORE")
    trees: dict[str, dict[str, str]] = {"after" if before else "": {}}
    if before:
        trees["before"] = before_environment(Path(before))
    rows = []
    for index, participants in enumerate(sizes):
        order = list(trees) if index % 2 == 0 else list(reversed(trees))
        measured = {}
        for code in order:
            print(f"  simulating {participants} participants {code}...", flush=True)
            measured[code] = _simulate(participants, trees[code])
        for code in trees:  # after, then before
            report = measured[code]
            row: dict[str, Any] = {"participants": participants, "code": code}
            if "violation" in report:
                rows.append({**row, "invariants": f"VIOLATED: {report['violation']}"})
                continue
            cpu = report["manager_cpu_per_activation"]
            rows.append(
                {
                    **row,
                    "invariants": "ok",
                    "messages": report["messages_per_activation"],
                    "cpu_ms": cpu * 1e3,
                    "cpu_per_participant_us": cpu / participants * 1e6,
                    "activation_ms": report["activation_time"] * 1e3,
                    "idle_messages": report["idle_messages_per_second"],
                    "idle_cpu_share": report["idle_manager_cpu_per_second"],
                    "status_period": report["status_period"],
                    "liveness_bound": report["liveness_bound"],
                    "detection_s": report["detection_time"],
                    "converge_s": report["time_to_converge"],
                    "commands": report["commands"],
                    "wall_s": report["wall_time"],
                    "load": os.getloadavg()[0],
                }
            )
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    coded = any(row["code"] for row in rows)
    lines = [
        f"| N |{' code |' if coded else ''} messages / sync activation | manager CPU / "
        "activation | per participant | activation (simulated) | idle: messages/s | idle: "
        "manager CPU | heartbeat period | liveness bound | crash to drop | converged after "
        "heal | commands | invariants | run time |",
        f"|---:|{'---|' if coded else ''}{'---:|' * 11}---|---:|",
    ]
    for row in rows:
        code = f" {row['code']} |" if coded else ""
        if row["invariants"] != "ok":
            lines.append(
                f"| {row['participants']} |{code}  |  |  |  |  |  |  |  |  |  |  | "
                f"{row['invariants']} |  |"
            )
            continue
        period = f"{row['status_period']:.2f} s" if row["status_period"] else "0.25 s (fixed)"
        bound = f"{row['liveness_bound']:.1f} s" if row["liveness_bound"] else "3.0 s (fixed)"
        drop = f"{row['detection_s']:.2f} s" if row["detection_s"] else "not measured"
        lines.append(
            f"| {row['participants']:,} |{code} {row['messages']:,.0f} | {row['cpu_ms']:.2f} ms "
            f"| {row['cpu_per_participant_us']:.1f} us | {row['activation_ms']:.1f} ms "
            f"| {row['idle_messages']:,.0f} | {row['idle_cpu_share'] * 100:.2f}% of a core "
            f"| {period} | {bound} | {drop} "
            f"| {row['converge_s']:.2f} s | {row['commands']} | ok | {row['wall_s']:.0f} s |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    sizes = tuple(int(n) for n in sys.argv[1:]) or SIZES
    print(markdown(run(sizes)))
