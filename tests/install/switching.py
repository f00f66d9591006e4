"""The end-to-end check of an installation: in a user's shell, the Layer manager, a Python
context node and a C++ context node switch layers together, synchronously."""

from __future__ import annotations

import os
import subprocess
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
