"""A colcon workspace of ContextROS over the ROS 2 wheels, by docs/install.md's commands as
written (the clone URL pointed at this checkout): the three ament packages build, and in the
sourced workspace the manager, a Python node and a C++ project built against the install
space switch together. Slow (a fresh venv and every build from scratch): `make test-slow`."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from tests.install.conftest import (
    REPOSITORY,
    install_commands,
    run_commands,
    user_environment,
)
from tests.install.switching import switch_together
from tests.ros.processes import ProcessGroup

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1200)]

HERE = Path(__file__).resolve().parent


def _shell_after(commands: str, cwd: Path) -> dict[str, str]:
    """Run the commands in bash; the environment they leave (what `. setup.bash` set)."""
    run_commands(
        commands + "\nenv -0 > ../.environment",
        env=user_environment(with_python=True),
        cwd=cwd,
        what="docs/install.md, colcon",
    )
    pairs = (cwd / ".environment").read_text().split("\0")
    return dict(pair.split("=", 1) for pair in pairs if "=" in pair)


def test_a_colcon_workspace_builds_and_switches_both_languages(
    tmp_path: Path, processes: ProcessGroup
) -> None:
    commands = install_commands("colcon").replace(
        "https://github.com/contextros/contextros", str(REPOSITORY)
    )
    assert str(REPOSITORY) in commands, "the colcon block no longer clones the repository"
    shell = _shell_after(commands, tmp_path)
    workspace = tmp_path / "ws"
    assert shell["CMAKE_PREFIX_PATH"].startswith(str(workspace / "install"))
    assert (
        workspace / "install" / "contextros_cpp" / "lib" / "contextros_cpp" / "cleaner_localization"
    ).exists()

    # A user's C++ project against the install space, with --cmake-prefix's answer.
    project = tmp_path / "examples" / "cpp_package"
    shutil.copytree(REPOSITORY / "examples" / "cpp_package", project)
    subprocess.run(
        ["bash", "-euo", "pipefail", "-c", install_commands("wheel-cpp")],
        env=shell,
        cwd=tmp_path,
        check=True,
        capture_output=True,
    )
    switch_together(
        shell,
        tmp_path / "build" / "greeter" / "greeter",
        HERE / "greeter_node.py",
        processes,
        tmp_path,
    )
