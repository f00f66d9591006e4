"""The pure protocol at fleet scale, simulated (issue 16): one manager and N participants in
`contextros.protocol.simulation` (no ROS: the protocol's own cost, not rclpy's). Each run:
start-up, 5 back-to-back synchronous activations on a clean link (measured), 10 s of faults
(20% loss, 10% duplication, 1-250 ms delay that reorders, 2 partitions of a tenth of the
nodes, 3 node crashes, 1 manager restart, 12 commands of every kind), then a heal. Every
guarantee is checked all along (`Invariants`: ok means none broke). Columns: messages on
the wire per synchronous activation; the manager's CPU per activation (real CPU of this
process inside the manager's state machine) and per participant; the activation's
simulated duration (a 0.5-2 ms link); messages per second and manager CPU share with
nothing happening (heartbeats: 4 per second each way per node); seconds from the heal to
every node live and on the manager's epoch. Replay a row with
`python -m contextros.protocol.simulation --seed 1 --participants N`.
"""

from __future__ import annotations

from typing import Any

from contextros.protocol.simulation import InvariantViolation, Scenario, simulate

SIZES = (10, 100, 1_000, 10_000)
SEED = 1


def run() -> list[dict[str, Any]]:
    rows = []
    for participants in SIZES:
        print(f"  simulating {participants} participants ...", flush=True)
        row: dict[str, Any] = {"participants": participants}
        try:
            report = simulate(Scenario(participants, SEED))
        except InvariantViolation as violation:
            row["invariants"] = f"VIOLATED: {str(violation).splitlines()[0]}"
            rows.append(row)
            continue
        row.update(
            invariants="ok",
            messages=report.messages_per_activation,
            cpu_ms=report.manager_cpu_per_activation * 1e3,
            cpu_per_participant_us=report.manager_cpu_per_activation / participants * 1e6,
            activation_ms=report.activation_time * 1e3,
            idle_messages=report.idle_messages_per_second,
            idle_cpu_share=report.idle_manager_cpu_per_second,
            converge_s=report.time_to_converge,
            commands=report.commands,
            wall_s=report.wall_time,
        )
        rows.append(row)
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| N | messages / sync activation | manager CPU / activation | per participant "
        "| activation (simulated) | idle: messages/s | idle: manager CPU | converged after "
        "heal | commands | invariants | run time |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for row in rows:
        if row["invariants"] != "ok":
            lines.append(
                f"| {row['participants']} |  |  |  |  |  |  |  |  | {row['invariants']} |  |"
            )
            continue
        lines.append(
            f"| {row['participants']:,} | {row['messages']:,.0f} | {row['cpu_ms']:.2f} ms "
            f"| {row['cpu_per_participant_us']:.1f} us | {row['activation_ms']:.1f} ms "
            f"| {row['idle_messages']:,.0f} | {row['idle_cpu_share'] * 100:.1f}% of a core "
            f"| {row['converge_s']:.2f} s | {row['commands']} | ok | {row['wall_s']:.0f} s |"
        )
    return "\n".join(lines)
