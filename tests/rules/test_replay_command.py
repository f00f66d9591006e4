"""`contextros rules replay` as a user runs it: a recording, rule files, the printed replay."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("mcap_ros2")

from tests.recording.test_reader import BATTERY_RULES, battery_recording, replay


@pytest.mark.parametrize(
    ("plot", "problem"),
    [
        ("missing/timeline.png", "no directory {tmp}/missing"),
        (".", "is a directory"),
    ],
)
def test_a_plot_that_cannot_be_written_is_a_usage_error_before_replaying(
    tmp_path: Path, plot: str, problem: str
) -> None:
    recording = battery_recording(tmp_path / "battery.mcap", [50.0, 10.0, 10.0, 10.0])
    rules = tmp_path / "robot.layers"
    rules.write_text(BATTERY_RULES, encoding="utf-8")
    target = tmp_path / plot
    done = replay(recording, rules, "--plot", str(target))
    assert done.returncode == 2, done.stderr
    expected = problem.format(tmp=tmp_path)
    assert done.stderr == f"contextros rules replay: --plot {target}: {expected}\n"
    assert done.stdout == ""  # nothing replayed
