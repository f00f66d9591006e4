"""A storm of commands (issue 16): 3 client processes send 600 commands each to one manager,
as fast as it answers (3 in flight per client), alternating asynchronous and
synchronous ones that switch Indoor <-> Outdoor; 4 context nodes (one worker process, one
participant) apply every state. Measured: commands per second over the whole storm (first
sent to last answered), whether every answer is exact (every command answered once; a
successful one's layers contain what it activated and not what it deactivated, and no
epoch is answered with two layer sets), and the manager's resident memory before, halfway
and after (flat: the storm leaves nothing behind). With `CONTEXTROS_BEFORE=<a source
tree>` the same storm runs on that tree's code too, in another ROS domain, alternately
(`ROUNDS` storms each). The clients spin lean and print their own CPU time, and the table
gives each side's CPU per command: on a 2-core machine, the storm's rate is bounded by the
sum of all of them, the manager's own capacity by its share.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.activation import _wait_for_lines
from benchmarks.code_before import before_environment

CLIENTS = 3
COMMANDS = 600  # per client
# Per client: the activation service keeps the last 10 requests (rclpy's default service
# QoS), so 3 clients with 3 commands in flight each never overflow it.
IN_FLIGHT = 3
LOST_AFTER = 10.0  # seconds without an answer: counted as lost (never a hang)
DOMAINS = {"after": 83, "before": 84}
TARGET = 1000.0  # commands per second
ROUNDS = 2  # storms per code, alternating with the code before (same machine load)


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (from /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def client(index: int, count: int) -> None:
    """One client process: waits for `go`, sends `count` commands, prints its answers."""
    import rclpy

    from contextros.ros import LayerClient
    from contextros.ros.wait_loop import WaitLoop

    rclpy.init()
    # A lean client, so that the clients' own cost hides the manager's less: no parameter
    # services, and one wait loop for the whole storm (`rclpy.spin_once(node)` adds the node
    # to the global executor and removes it again on every call).
    node = rclpy.create_node(f"storm_client{index}", start_parameter_services=False)
    layers = LayerClient(node, requester=f"storm{index}")
    layers.wait_for_manager(60)
    print(json.dumps("ready"), flush=True)
    sys.stdin.readline()
    cpu = time.process_time()
    answers: list[dict[str, Any]] = []
    pending: list[tuple[Any, str, bool, float]] = []
    lost: list[dict[str, Any]] = []
    sent = 0
    started = time.monotonic()
    loop = WaitLoop([node])
    while len(answers) + len(lost) < count:
        while sent < count and len(pending) < IN_FLIGHT:
            on, off = ("Indoor", "Outdoor") if (sent + index) % 2 else ("Outdoor", "Indoor")
            synchronous = sent % 2 == 1
            future = layers.request_async([on], [off], synchronous=synchronous, timeout=5.0)
            pending.append((future, on, synchronous, time.monotonic()))
            sent += 1
        loop.spin_once(timeout_sec=0.05)
        still = []
        for future, on, synchronous, sent_at in pending:
            if not future.done():
                if time.monotonic() - sent_at > LOST_AFTER:
                    # Which command and when: a lost answer stalls its client LOST_AFTER s.
                    lost.append({"sync": synchronous, "sent_at": round(sent_at - started, 3)})
                else:
                    still.append((future, on, synchronous, sent_at))
                continue
            result = layers.result_of(future)
            answers.append(
                {
                    "on": on,
                    "sync": synchronous,
                    "success": result.success,
                    "epoch": result.epoch,
                    "active": list(result.active),
                    "message": result.message,
                }
            )
        pending = still
    cpu = time.process_time() - cpu
    print(json.dumps(answers), flush=True)
    print(json.dumps({"lost": lost, "cpu": cpu}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


class _Storm:
    def __init__(self, label: str, tree: Path | None) -> None:
        from examples.launch import Launch

        extra = before_environment(tree) if tree is not None else {}
        self.label = label
        self.launch = Launch(DOMAINS[label], grace=5.0, extra_env=extra)
        self.manager = self.launch.start_module(
            "manager", "contextros", "manager", "--recovery-window", "0.3"
        )
        names = [f"storm_{label}_n{index}" for index in range(4)]
        self.worker = self.launch.start_module("worker", "benchmarks.activation", "worker", *names)
        _wait_for_lines(self.launch, "ready", 1)

    def run(self) -> dict[str, Any]:
        clients = [
            subprocess.Popen(
                [sys.executable, "-m", "benchmarks.storm", "client", str(i), str(COMMANDS)],
                cwd=Path(__file__).resolve().parent.parent,
                env=self.launch.env,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                bufsize=1,
            )
            for i in range(CLIENTS)
        ]
        try:
            for process in clients:
                assert process.stdout is not None
                json.loads(process.stdout.readline())
            time.sleep(1.0)  # every participant registered, the first state applied
            memory = [_rss_kib(self.manager.pid)]
            processes = {"manager": self.manager.pid, "participants": self.worker.pid}
            cpu = {name: -_cpu_seconds(pid) for name, pid in processes.items()}
            started = time.perf_counter()
            for process in clients:
                assert process.stdin is not None
                process.stdin.write("go\n")
                process.stdin.flush()
            answers: list[dict[str, Any]] = []
            lost: list[dict[str, Any]] = []
            cpu["clients"] = 0.0
            for process in clients:
                assert process.stdout is not None
                answers += json.loads(process.stdout.readline())
                memory.append(_rss_kib(self.manager.pid))
                end = json.loads(process.stdout.readline())
                lost += end["lost"]
                cpu["clients"] += end["cpu"]
            elapsed = time.perf_counter() - started
            for name, pid in processes.items():
                cpu[name] += _cpu_seconds(pid)
        finally:
            for process in clients:
                process.kill()
                process.wait()
        return {
            "answers": answers,
            "elapsed": elapsed,
            "memory": memory,
            "lost": lost,
            "cpu": cpu,
            "load": os.getloadavg()[0],
        }

    def close(self) -> None:
        self.launch.stop_all()


def _exactness(answers: list[dict[str, Any]], lost: list[dict[str, Any]]) -> str:
    """ "" if every answer is exact, else what is not."""
    if len(answers) != CLIENTS * COMMANDS:
        when = ", ".join(f"{'sync' if c['sync'] else 'async'} at {c['sent_at']} s" for c in lost)
        return f"{len(answers)} answers to {CLIENTS * COMMANDS} commands (lost: {when})"
    layers_of: dict[int, tuple[str, ...]] = {}
    for answer in answers:
        active = tuple(answer["active"])
        known = layers_of.setdefault(answer["epoch"], active)
        if known != active:
            return f"epoch {answer['epoch']} answered as {known} and {active}"
        if not answer["success"]:
            return f"a command failed: {answer['message']}"
        off = "Outdoor" if answer["on"] == "Indoor" else "Indoor"
        if answer["on"] not in active or off in active:
            return f"a success turning {answer['on']} on answered {active}"
    return ""


def run() -> list[dict[str, Any]]:
    before = os.environ.get("CONTEXTROS_BEFORE")
    trees: dict[str, Path | None] = {"after": None}
    if before:
        trees["before"] = Path(before)
    rows = []
    for label, tree in [item for _ in range(ROUNDS) for item in trees.items()]:
        print(f"  storm: {label}", flush=True)
        storm = _Storm(label, tree)
        try:
            outcome = storm.run()
        finally:
            storm.close()
        answers = outcome["answers"]
        memory = outcome["memory"]
        rows.append(
            {
                "code": label,
                "commands": len(answers),
                "per_second": len(answers) / outcome["elapsed"],
                "exact": _exactness(answers, outcome["lost"]) or "yes",
                "memory_kib": memory,
                "synchronous": sum(a["sync"] for a in answers),
                # CPU milliseconds per command, per side, over the storm.
                "cpu_ms": {
                    name: 1000 * seconds / max(len(answers), 1)
                    for name, seconds in outcome["cpu"].items()
                },
                "load": outcome["load"],
            }
        )
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| code | commands (of which synchronous) | commands/s | target >= 1000/s "
        "| every answer exact | manager memory: before, after each client's end "
        "| CPU per command: manager, participants' process, 3 clients "
        "| manager's core would serve | load average |",
        "|---|---:|---:|---|---|---|---|---:|---:|",
    ]
    for row in rows:
        verdict = "met" if row["per_second"] >= TARGET else "missed"
        memory = ", ".join(f"{kib / 1024:.1f}" for kib in row["memory_kib"])
        cpu = row["cpu_ms"]
        capacity = 1000 / cpu["manager"] if cpu["manager"] > 0 else float("inf")
        lines.append(
            f"| {row['code']} | {row['commands']} ({row['synchronous']}) "
            f"| {row['per_second']:.0f} | {verdict} | {row['exact']} | {memory} MiB "
            f"| {cpu['manager']:.2f}, {cpu['participants']:.2f}, {cpu['clients']:.2f} ms "
            f"| {capacity:.0f}/s | {row['load']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv[:1] == ["client"]:
        client(int(argv[1]), int(argv[2]))
        return 0
    print(markdown(run()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
