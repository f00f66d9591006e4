"""The wheel, installed as a user installs it (docs/install.md): in a fresh venv, the Layer
manager, a Python context node and a C++ node of the user's own CMake project switch layers
together, synchronously; a missing piece is one clear line, not a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.install.conftest import user_environment
from tests.install.switching import switch_together
from tests.ros.processes import ProcessGroup

HERE = Path(__file__).resolve().parent
# The first test builds the wheel and the venv (a minute on a quiet 2-core machine).
pytestmark = pytest.mark.timeout(900)


def test_python_and_cpp_nodes_of_the_wheel_switch_together(
    user_venv: Path, cpp_package: Path, processes: ProcessGroup, tmp_path: Path
) -> None:
    switch_together(
        user_environment(user_venv), cpp_package, HERE / "greeter_node.py", processes, tmp_path
    )


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
        [
            getattr(sys, "_base_executable", sys.executable),
            "-m",
            "venv",
            "--without-pip",
            str(venv),
        ],
        check=True,
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
    # The Python API: the error names what is missing (a LayerError and an ImportError).
    done = subprocess.run(
        [str(venv / "bin" / "python"), "-c", "from contextros.ros import ContextNode"],
        env=shell, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert done.returncode == 1
    assert "RosUnavailableError: rclpy (ROS 2's Python client library) cannot be imported" in (
        done.stderr
    ), done.stderr


def test_the_installed_wheel_dispatches_in_c(user_venv: Path) -> None:
    """The wheel carries the core's C dispatcher and its import selects it."""
    shown = subprocess.run(
        [
            str(user_venv / "bin" / "python"),
            "-c",
            "import contextros.core, contextros.core._dispatch as d; "
            "print(contextros.core.DISPATCHER, d.__file__)",
        ],
        env=user_environment(user_venv),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assert shown[0] == "c"
    assert Path(shown[1]).is_relative_to(user_venv)
