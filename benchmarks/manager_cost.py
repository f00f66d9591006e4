"""The Layer manager's own cost per synchronous activation, one participant per node
(issue 16). Set-up: the manager (`contextros manager`) in its own process, N context nodes
with a participant each (`share_participant=False`) in 8 worker processes, a caller
process sending back-to-back synchronous activations (Indoor <-> Outdoor, 2 ms apart).
Measured: the manager's `elapsed` (command received -> last acknowledgement), and the
manager process's CPU time (user + system, from /proc) per activation and per participant,
less its idle rate (heartbeats) measured just before. With `CONTEXTROS_BEFORE=<a source
tree>` the same system runs a second time on that tree's code, in another ROS domain, with
the rounds of the two interleaved (blocks of 10), so both see the same machine load.

On a loaded machine an activation can take hundreds of milliseconds (the workers wait
for a core); the idle rate subtracted over that time then swamps the activation's own
cost, and such a row says "not measurable" rather than a verdict.

Profile the manager the same way: `python -m benchmarks.manager_cost --profile out.svg`
(py-spy records the manager process during the rounds; `out.txt`: collapsed stacks).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.activation import NODES_PER_PROCESS, _wait_for_lines
from benchmarks.code_before import before_environment, trees_to_compare

NODE_COUNTS = (1, 16, 64)
ROUNDS = 40
BLOCK = 10
# The ROS domains of the two systems (`CONTEXTROS_BENCH_DOMAIN=N`: N and N + 1 instead).
_FIRST = int(os.environ.get("CONTEXTROS_BENCH_DOMAIN", "81"))
DOMAINS = {"after": _FIRST, "before": _FIRST + 1}
TARGET_CPU_PER_PARTICIPANT_MS = 0.05  # issue 26 (0.1 in issue 16)


def _cpu_seconds(pid: int) -> float:
    """The process's CPU time: its threads' run time in ns (schedstat), where /proc/PID/stat
    counts 10 ms ticks (a 1 s idle rate was 2% or 3%, nothing between)."""
    try:
        return (
            sum(
                int((task / "schedstat").read_text().split()[0])
                for task in Path(f"/proc/{pid}/task").iterdir()
            )
            / 1e9
        )
    except (OSError, ValueError, IndexError):  # a thread ended meanwhile: ticks
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class _System:
    """A manager, its participants and a caller process, on one tree's code."""

    def __init__(
        self,
        label: str,
        tree: Path | None,
        count: int,
        lean: bool = False,
        domain: int | None = None,
    ) -> None:
        from examples.launch import Launch

        extra = before_environment(tree) if tree is not None else {}
        self.label, self.count = label, count
        self.launch = Launch(
            DOMAINS[label] if domain is None else domain, grace=5.0, extra_env=extra
        )
        self.manager = self.launch.start_module(
            "manager", "contextros", "manager", "--recovery-window", "0.3"
        )
        processes = min(NODES_PER_PROCESS, count)
        names = [f"cost_{label}_{count}_n{index:02d}" for index in range(count)]
        self.workers = []
        for process in range(processes):
            own = names[process::processes]
            options = ["--per-node", *(["--lean"] if lean else [])]
            self.workers.append(
                self.launch.start_module(
                    f"worker{process}", "benchmarks.activation", "worker", *own, *options
                )
            )
        _wait_for_lines(self.launch, "ready", processes)
        self.caller = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.manager_cost", "caller", str(count)],
            cwd=Path(__file__).resolve().parent.parent,
            env=self.launch.env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            bufsize=1,
        )
        self._ask("ready")

    def _ask(self, line: str) -> Any:
        assert self.caller.stdin is not None and self.caller.stdout is not None
        self.caller.stdin.write(line + "\n")
        self.caller.stdin.flush()
        answer = self.caller.stdout.readline()
        if not answer:
            raise RuntimeError(f"{self.label}: the caller process exited")
        return json.loads(answer)

    def idle_rate(self, seconds: float = 1.0) -> float:
        return self.idle_rate_of([self.manager.pid], seconds)

    def block(self, rounds: int) -> tuple[list[float], float]:
        """`rounds` activations: their `elapsed`, and the manager's CPU per activation."""
        elapsed, cpu = self.block_of([self.manager.pid], rounds)
        return elapsed, cpu

    def block_of(self, pids: list[int], rounds: int) -> tuple[list[float], float]:
        """`rounds` activations: their `elapsed`, and the CPU of the processes `pids` per
        activation, less their idle rate measured just before."""
        idle = self.idle_rate_of(pids, 0.5)
        started, before = time.monotonic(), sum(map(_cpu_seconds, pids))
        elapsed = self._ask(f"rounds {rounds}")
        spent = sum(map(_cpu_seconds, pids)) - before
        cpu = max(0.0, spent - idle * (time.monotonic() - started)) / rounds
        return elapsed, cpu

    def idle_rate_of(self, pids: list[int], seconds: float) -> float:
        before = sum(map(_cpu_seconds, pids))
        time.sleep(seconds)
        return (sum(map(_cpu_seconds, pids)) - before) / seconds

    def pause(self, paused: bool) -> None:
        """Stop (SIGSTOP) or continue every process of this system: a paused system uses
        no CPU while the other one is measured."""
        for process in [*self.launch.processes.values(), self.caller]:
            if process.poll() is None:
                process.send_signal(signal.SIGSTOP if paused else signal.SIGCONT)

    def close(self) -> None:
        self.pause(False)
        if self.caller.poll() is None:
            self.caller.kill()
            self.caller.wait()
        self.launch.stop_all()


def caller(count: int) -> None:
    """The caller process: `ready`, then `rounds N` -> the N `elapsed` (JSON), one line each."""
    import rclpy

    from contextros.ros import LayerClient

    rclpy.init()
    node = rclpy.create_node("cost_caller")
    client = LayerClient(node, requester="bench")
    for line in sys.stdin:
        words = line.split()
        if words[0] == "ready":
            client.wait_for_manager(60)
            deadline = time.monotonic() + 60
            while len(client.query().participants) < count or client.query().epoch < 1:
                if time.monotonic() > deadline:
                    raise TimeoutError("participants did not join")
                time.sleep(0.1)
            print(json.dumps("ok"), flush=True)
        else:
            elapsed = []
            for index in range(int(words[1])):
                on, off = ("Indoor", "Outdoor") if index % 2 else ("Outdoor", "Indoor")
                result = client.request([on], [off], synchronous=True, timeout=5.0)
                elapsed.append(result.elapsed if result.success else math.nan)
                time.sleep(0.002)
            print(json.dumps(elapsed), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def run(
    node_counts: tuple[int, ...] = NODE_COUNTS, rounds: int = ROUNDS, profile: str = ""
) -> list[dict[str, Any]]:
    trees = trees_to_compare()
    rows = []
    for count in node_counts:
        print(f"  manager cost: {count} participants", flush=True)
        systems = {label: _System(label, tree, count) for label, tree in trees.items()}
        spy = None
        try:
            if profile:
                pid = systems["after"].manager.pid
                raw = ["-f", "raw"] if profile.endswith(".txt") else []  # collapsed stacks
                spy = subprocess.Popen(
                    ["py-spy", "record", "--pid", str(pid), "-o", profile, "--rate", "200", *raw]
                )
            samples: dict[str, list[float]] = {label: [] for label in systems}
            cpu: dict[str, list[float]] = {label: [] for label in systems}
            idle = {label: system.idle_rate() for label, system in systems.items()}
            for index in range(math.ceil(rounds / BLOCK)):
                order = list(systems) if index % 2 == 0 else list(reversed(systems))
                for label in order:
                    elapsed, spent = systems[label].block(BLOCK)
                    samples[label] += [e for e in elapsed if not math.isnan(e)]
                    cpu[label].append(spent)
        finally:
            if spy is not None:
                spy.send_signal(2)
                spy.wait()
            for system in systems.values():
                system.close()
        for label in systems:
            row = cost_row(samples[label], cpu[label], count, rounds)
            rows.append({"code": label, **row, "idle_cpu": idle[label]})
    return rows


def cost_row(elapsed: list[float], cpu: list[float], count: int, rounds: int) -> dict[str, Any]:
    """One row of a cost table: the activations' median and p90, the samples lost, and the
    median CPU per activation (and per participant) of the processes measured."""
    ordered = sorted(elapsed)
    per_activation = statistics.median(cpu)
    return {
        "participants": count,
        "median_ms": statistics.median(ordered) * 1e3 if ordered else math.nan,
        "p90_ms": ordered[int(0.9 * (len(ordered) - 1))] * 1e3 if ordered else math.nan,
        "lost": rounds - len(ordered),
        "cpu_ms": per_activation * 1e3,
        "cpu_per_participant_ms": per_activation * 1e3 / count,
        "load": os.getloadavg()[0],
    }


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| code | participants | sync activation, median | p90 | manager CPU / activation "
        f"| per participant | target <= {TARGET_CPU_PER_PARTICIPANT_MS:g} ms | manager idle CPU "
        "| load average |",
        "|---|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for row in rows:
        per = row["cpu_per_participant_ms"]
        verdict = "met" if per <= TARGET_CPU_PER_PARTICIPANT_MS else "missed"
        if row["participants"] == 1:
            verdict = "(N=1: fixed costs)"
        elif row["cpu_ms"] <= 0 or row["median_ms"] > 100:
            # The idle rate subtracted over activations this slow swamps their own cost.
            verdict = "not measurable: machine overloaded"
        lines.append(
            f"| {row['code']} | {row['participants']} | {row['median_ms']:.1f} ms "
            f"| {row['p90_ms']:.1f} ms | {row['cpu_ms']:.2f} ms | {per:.3f} ms | {verdict} "
            f"| {row['idle_cpu'] * 100:.2f}% | {row.get('load', math.nan):.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv[:1] == ["caller"]:
        caller(int(argv[1]))
        return 0
    parser = argparse.ArgumentParser(description="the manager's cost per activation")
    parser.add_argument("--nodes", type=int, nargs="+", default=list(NODE_COUNTS))
    parser.add_argument("--rounds", type=int, default=ROUNDS)
    parser.add_argument("--profile", default="", help="py-spy output of the manager (after)")
    args = parser.parse_args(argv)
    print(markdown(run(tuple(args.nodes), args.rounds, args.profile)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
