"""`contextros rules replay` as a user runs it: a recording, rule files, the printed replay."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("mcap_ros2")
from mcap_ros2.writer import Writer

from contextros.recording.definitions import message_definition
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


def test_a_manual_switch_with_no_reason_prints_a_dash_as_watch_and_status_do(
    tmp_path: Path,
) -> None:
    recording = tmp_path / "manual.mcap"
    state_type = "contextros_interfaces/msg/LayerState"
    with recording.open("wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef(state_type, message_definition(state_type))
        for second, (epoch, active, requester) in enumerate(
            [(1, [], "manager"), (2, ["LowBattery"], "root@pid18551")]
        ):
            state = {"epoch": epoch, "active_layers": active, "requester": requester}
            at = int((100 + second) * 1e9)
            writer.write_message("/contextros/state", schema, state, log_time=at)
        writer.finish()
    rules = tmp_path / "robot.layers"
    rules.write_text(BATTERY_RULES, encoding="utf-8")
    done = replay(recording, rules)
    assert done.returncode == 0, done.stderr
    assert "    1.000 s  [LowBattery]  root@pid18551: -\n" in done.stdout, done.stdout
