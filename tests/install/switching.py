"""The end-to-end check of an installation: in a user's shell, the Layer manager, a Python
context node and a C++ context node switch layers together, synchronously."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

from tests.ros.processes import Child, ProcessGroup


def line_with(child: Child, text: str, timeout: float = 10.0) -> str:
    """The last line of `child` containing `text`, waiting for it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = [line for line in child.lines if text in line]
        if found:
            return found[-1]
        if child.popen.poll() is not None:
            break
        time.sleep(0.05)
    raise AssertionError(f"{child.name}: no line with {text!r}; output:\n{child.output()}")


def switch_together(
    shell: Mapping[str, str],
    cpp_node: Path,
    python_node: Path,
    processes: ProcessGroup,
    cwd: Path,
) -> None:
    """`contextros` and `python` as the shell finds them; cpp_node and python_node are the
    greeter of examples/cpp_package and tests/install/greeter_node.py."""
    env: dict[str, str | None] = {name: None for name in set(os.environ) - set(shell)}
    env.update(shell)

    def start(name: str, program: str, *argv: str) -> Child:
        child = Child(name, argv, env=env, program=program)
        processes.children.append(child)
        return child

    manager = start("manager", "contextros", "manager")
    python = start("python node", "python", str(python_node))
    cpp = start("C++ node", str(cpp_node))
    line_with(python, "ready")
    line_with(cpp, "ready")

    def command(*argv: str) -> str:
        done = subprocess.run(
            ["contextros", *argv],
            env=dict(shell),
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert done.returncode == 0, done.stdout + done.stderr + manager.output()
        return done.stdout

    answer = command(
        "activate", "Tokyo", "--sync", "--expect", "/greeter_py", "/greeter_cpp",
        "--wait-manager", "10",
    )  # fmt: skip
    assert "acknowledged by 2 node(s)" in answer, answer
    assert line_with(python, "[Tokyo]").endswith("konnichiwa")
    assert line_with(cpp, "[Tokyo]").endswith("konnichiwa")

    answer = command("switch", "--on", "London", "--off", "Tokyo", "--sync")
    assert "acknowledged by 2 node(s)" in answer, answer
    assert line_with(python, "[London]").endswith("good morning")
    assert line_with(cpp, "[London]").endswith("good morning")

    check_the_daemon(shell, cwd, {"/greeter_py", "/greeter_cpp"})


def check_the_daemon(shell: Mapping[str, str], cwd: Path, nodes: set[str]) -> None:
    """The CLI's daemon, from the installation (docs/cli.md section 10): the first command
    starts it, and the next one is answered by it, importing no rclpy."""
    runtime = tempfile.mkdtemp(prefix="crd-install-")  # short: a socket's path is limited
    env = {**shell, "CONTEXTROS_RUNTIME_DIR": runtime}
    env.pop("CONTEXTROS_NO_DAEMON", None)

    def contextros(*argv: str, **extra: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            ["contextros", *argv],
            env=env | extra,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=60,
        )

    try:
        first = contextros("status", "--json")
        assert first.returncode == 0, first.stderr
        deadline = time.monotonic() + 20
        while contextros("daemon", "status").returncode != 0:
            assert time.monotonic() < deadline, f"no daemon started; {first.stderr}"
            time.sleep(0.2)
        served = contextros("status", "--json", PYTHONPROFILEIMPORTTIME="1")
        assert served.returncode == 0, served.stderr
        imported = {line.rpartition("|")[2].strip() for line in served.stderr.splitlines()}
        assert not [m for m in imported if m.split(".")[0] == "rclpy"], "it asked itself"
        shown = {p["node"] for p in json.loads(served.stdout)["participants"]}
        assert nodes <= shown, shown
        stopped = contextros("daemon", "stop")
        assert stopped.returncode == 0 and "stopped" in stopped.stdout, stopped.stdout
    finally:
        contextros("daemon", "stop", "--all")
        shutil.rmtree(runtime, ignore_errors=True)
