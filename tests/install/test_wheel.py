"""The wheel, installed as a user installs it (docs/install.md): in a fresh venv, the Layer
manager, a Python context node and a C++ node of the user's own CMake project switch layers
together, synchronously; a missing piece is one clear line, not a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.install.conftest import user_environment
from tests.ros.processes import Child, ProcessGroup

HERE = Path(__file__).resolve().parent


def _lines_with(child: Child, text: str, timeout: float = 10.0) -> str:
    """Wait for a line of `child` containing `text`."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = [line for line in child.lines if text in line]
        if found:
            return found[-1]
        if child.popen.poll() is not None:
            break
        time.sleep(0.05)
    raise AssertionError(f"{child.name}: no line with {text!r}; output:\n{child.output()}")


def test_python_and_cpp_nodes_of_the_wheel_switch_together(
    user_venv: Path, cpp_package: Path, processes: ProcessGroup, tmp_path: Path
) -> None:
    shell = user_environment(user_venv)
    unset = {name: None for name in set(__import__("os").environ) - set(shell)}
    env = {**unset, **shell}
    contextros = str(user_venv / "bin" / "contextros")
    python = str(user_venv / "bin" / "python")

    def start(name: str, program: str, *argv: str) -> Child:
        child = Child(name, argv, env=env, program=program)
        processes.children.append(child)
        return child

    manager = start("manager", contextros, "manager")
    python_node = start("python node", python, str(HERE / "greeter_node.py"))
    cpp_node = start("C++ node", str(cpp_package))
    _lines_with(python_node, "ready")
    _lines_with(cpp_node, "ready")

    def command(*argv: str) -> str:
        done = subprocess.run(
            [contextros, *argv],
            env=shell,
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert done.returncode == 0, done.stdout + done.stderr + manager.output()
        return done.stdout

    answer = command(
        "activate",
        "Tokyo",
        "--sync",
        "--expect",
        "/greeter_py",
        "/greeter_cpp",
        "--wait-manager",
        "10",
    )
    assert "acknowledged by 2 node(s)" in answer, answer
    assert _lines_with(python_node, "[Tokyo]").endswith("konnichiwa")
    assert _lines_with(cpp_node, "[Tokyo]").endswith("konnichiwa")

    answer = command("switch", "--on", "London", "--off", "Tokyo", "--sync")
    assert "acknowledged by 2 node(s)" in answer, answer
    assert _lines_with(python_node, "[London]").endswith("good morning")
    assert _lines_with(cpp_node, "[London]").endswith("good morning")


def test_the_version_is_one_number(user_venv: Path) -> None:
    shell = user_environment(user_venv)
    shown = subprocess.run(
        [str(user_venv / "bin" / "contextros"), "--version"],
        env=shell,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()[-1]
    metadata = subprocess.run(
        [
            str(user_venv / "bin" / "python"),
            "-c",
            "import importlib.metadata as m; print(m.version('contextros'))",
        ],
        env=shell,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert shown == metadata
    from contextros import __version__

    assert shown == __version__


def test_a_missing_piece_is_named_with_what_to_install(tmp_path: Path) -> None:
    """A venv with the contextros wheel's Python package but no ROS 2 at all."""
    venv = tmp_path / "bare"
    subprocess.run(
        [getattr(sys, "_base_executable", sys.executable), "-m", "venv", str(venv)], check=True
    )
    shell = user_environment(
        venv, PYTHONPATH=str(Path(__import__("contextros").__file__).parents[1])
    )
    for argv in (["manager"], ["activate", "Indoor"], ["status"]):
        done = subprocess.run(
            [str(venv / "bin" / "python"), "-m", "contextros", *argv],
            env=shell,
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert done.returncode == 2, done.stderr
        assert "Traceback" not in done.stderr, done.stderr
        assert "rclpy" in done.stderr and "docs/install.md" in done.stderr, done.stderr
