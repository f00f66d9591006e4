"""A CLI client command on a running system, from process start to exit (issues 12, 16).

Set-up: the Layer manager (`contextros manager`) and one process with a context node
(the cleaner's Indoor/Outdoor layers, as in the activation benchmark) run in a domain of
their own. Each sample starts a fresh `python -m contextros activate Indoor|Outdoor --sync`
and measures the wall time until that process exits. The command goes through the CLI's
daemon (`contextros daemon`, started before the rounds in a directory of the benchmark's
own): interpreter start, the CLI's imports, one local round trip and the synchronous
activation. With `--no-daemon` the command does everything itself (what the first command,
the one that starts the daemon, costs): imports, ROS start-up, discovery of the manager's
service, the activation and shutdown. For reference, in the same rounds:
`python -m contextros --version` (interpreter start and the package's own imports only), and
the floor any rclpy command has: a plain rclpy script (`python -m benchmarks.cli_command
plain LAYER`) that sends the same request to the manager's activation service (import rclpy
and the service type, init, a node, wait for the service, call, shut down) with nothing of
ContextROS. With `CONTEXTROS_BEFORE=<a source tree>`, that tree's `contextros activate` runs
in the same rounds too (against the same manager), through its daemon and with `--no-daemon`.
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.activation import BENCH_DOMAIN_ID, _wait_for_lines
from benchmarks.code_before import before_environment

ROUNDS = 20
TARGET_P90_S = 0.5
COMMAND = "contextros activate LAYER --sync"
NO_DAEMON = "contextros activate LAYER --sync --no-daemon"
VERSION = "contextros --version"
PLAIN = "python -m benchmarks.cli_command plain LAYER"
BEFORE = "before: contextros activate LAYER --sync"
BEFORE_NO_DAEMON = "before: contextros activate LAYER --sync --no-daemon"


def plain(layer: str) -> int:
    """The same synchronous activation in plain rclpy: what any rclpy command costs."""
    import rclpy
    from contextros_interfaces.srv import Activate

    rclpy.init()
    node = rclpy.create_node("plain_cli")
    client = node.create_client(Activate, "/contextros/activate")
    deadline = time.monotonic() + 10.0
    while not client.service_is_ready() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.01)
    request = Activate.Request(activate=[layer], synchronous=True, timeout=5.0)
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
    success = future.done() and future.result().success
    node.destroy_node()
    rclpy.try_shutdown()
    return 0 if success else 1


def _run(
    arguments: list[str], env: dict[str, str], module: str = "contextros"
) -> tuple[float, int, str]:
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", module, *arguments],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    return time.perf_counter() - started, done.returncode, done.stderr.strip()


def _check_served_by_daemon(env: dict[str, str]) -> None:
    """The daemon row must measure the daemon: a command it answers imports no rclpy."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "contextros", "status"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    imported = {line.rpartition("|")[2].strip() for line in done.stderr.splitlines()}
    if done.returncode != 0 or any(name.split(".")[0] == "rclpy" for name in imported):
        raise RuntimeError(f"the daemon did not answer a command: {done.stderr[-500:]}")


def run(rounds: int = ROUNDS) -> list[dict[str, Any]]:
    from examples.launch import Launch, ros_environment

    domain = int(os.environ.get("CONTEXTROS_BENCH_DOMAIN_ID", BENCH_DOMAIN_ID)) + 1
    runtime = tempfile.mkdtemp(prefix="crd-bench-")
    env = ros_environment(domain) | {"CONTEXTROS_RUNTIME_DIR": runtime}
    env.pop("CONTEXTROS_NO_DAEMON", None)
    cases = [COMMAND, NO_DAEMON, PLAIN, VERSION]
    tree = os.environ.get("CONTEXTROS_BEFORE")
    before_env = env | before_environment(Path(tree)) if tree else {}
    if tree:
        cases += [BEFORE, BEFORE_NO_DAEMON]
    samples: dict[str, list[float]] = {case: [] for case in cases}
    failures = dict.fromkeys(cases, 0)
    load_before = os.getloadavg()[0]
    try:
        with Launch(domain, grace=5.0) as launch:
            launch.start_module("manager", "contextros", "manager", "--recovery-window", "0.3")
            launch.start_module("worker", "benchmarks.activation", "worker", "bench_cli_node")
            _wait_for_lines(launch, "ready", 1)
            _run(["daemon", "start"], env)
            # Until the manager knows the node (its first states are recovery).
            for _ in range(50):
                _, status, _ = _run(["activate", "Indoor", "--sync", "--timeout", "5"], env)
                if status == 0:
                    break
                time.sleep(0.2)
            _check_served_by_daemon(env)
            layer = "Outdoor"
            commands = {
                COMMAND: (["activate", "LAYER", "--sync", "--timeout", "5"], env, "contextros"),
                NO_DAEMON: (
                    ["activate", "LAYER", "--sync", "--timeout", "5", "--no-daemon"],
                    env,
                    "contextros",
                ),
                PLAIN: (["plain", "LAYER"], env, "benchmarks.cli_command"),
                VERSION: (["--version"], env, "contextros"),
                BEFORE: (
                    ["activate", "LAYER", "--sync", "--timeout", "5"],
                    before_env,
                    "contextros",
                ),
                BEFORE_NO_DAEMON: (
                    ["activate", "LAYER", "--sync", "--timeout", "5", "--no-daemon"],
                    before_env,
                    "contextros",
                ),
            }
            for _ in range(rounds):
                for case in cases:
                    arguments, case_env, module = commands[case]
                    arguments = [layer if word == "LAYER" else word for word in arguments]
                    elapsed, status, error = _run(arguments, case_env, module)
                    if status == 0:
                        samples[case].append(elapsed)
                    else:
                        failures[case] += 1
                        print(f"  {case}: exit {status}: {error}", file=sys.stderr, flush=True)
                    if "LAYER" in commands[case][0]:  # each command switches
                        layer = "Indoor" if layer == "Outdoor" else "Outdoor"
    finally:
        _run(["daemon", "stop", "--all"], env)
        if tree:  # a tree with a daemon of its own started one too
            _run(["daemon", "stop", "--all"], before_env)
        shutil.rmtree(runtime, ignore_errors=True)
    rows = []
    for case, values in samples.items():
        ordered = sorted(values)
        rows.append(
            {
                "case": case,
                "samples": len(ordered),
                "failed": failures[case],
                "median_s": statistics.median(ordered) if ordered else float("nan"),
                "p90_s": ordered[int(0.9 * (len(ordered) - 1))] if ordered else float("nan"),
                "max_s": ordered[-1] if ordered else float("nan"),
                "load": (load_before, os.getloadavg()[0]),
            }
        )
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| command (new process each time) | median [s] | p90 [s] | max [s] | samples | failed "
        "| target |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for row in rows:
        target = ""
        if row["case"] == COMMAND:
            met = row["p90_s"] <= TARGET_P90_S
            target = f"p90 <= {TARGET_P90_S:g} s: {'met' if met else 'MISSED'}"
        lines.append(
            f"| `{row['case']}` | {row['median_s']:.3f} | {row['p90_s']:.3f} | "
            f"{row['max_s']:.3f} | {row['samples']} | {row['failed']} | {target} |"
        )
    before, after = rows[0]["load"]
    lines += [
        "",
        f"Load average (1 min) at the start and end: {before:.1f} and {after:.1f}, on 2 "
        "cores shared with other jobs.",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    if sys.argv[1:2] == ["plain"]:
        sys.exit(plain(sys.argv[2]))
    print(markdown(run()))
