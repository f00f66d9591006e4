"""`contextros manager --layers` takes layer files (docs/cli.md): a directory is refused at
once (exit 2) with a message naming it, where `contextros check` searches it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def _contextros(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "contextros", *arguments],
        capture_output=True,
        text=True,
        timeout=20,  # a manager that accepted its files would run until stopped
    )


def test_the_manager_refuses_a_directory_of_layer_files_check_searches(tmp_path: Path) -> None:
    folder = tmp_path / "robot"
    folder.mkdir()
    (folder / "robot.layers").write_text(
        "rule Low: Night while battery.percent < 20\n", encoding="utf-8"
    )
    assert _contextros("check", str(folder)).returncode == 0
    manager = _contextros("manager", "--layers", str(folder))
    assert manager.returncode == 2, manager.stderr
    assert manager.stderr.splitlines() == [
        "contextros manager: the layer files have errors:",
        f"{folder}: error: a directory, not a layer file (name its layer files: DIR/*.layers)",
    ]
