"""Reading recordings: another writer's file, damaged files, types this reader cannot decode."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mcap_ros2")
from mcap.writer import Writer as McapWriter
from mcap_ros2.writer import Writer

from contextros.recording import RecordingError, read_recording
from contextros.recording.definitions import message_definition

BATTERY_RULES = "rule Low: LowBattery while battery.percentage < 20 for 1 s hysteresis 5\n"


def battery_recording(path: Path, percentages: list[float], period: float = 0.5) -> Path:
    """BatteryState messages on /battery, written by the mcap ROS 2 writer (not ours)."""
    with path.open("wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef(
            "sensor_msgs/msg/BatteryState", message_definition("sensor_msgs/msg/BatteryState")
        )
        for index, percentage in enumerate(percentages):
            at = int((100 + index * period) * 1e9)
            writer.write_message("/battery", schema, {"percentage": percentage}, log_time=at)
        writer.finish()
    return path


def replay(recording: Path, rules: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "contextros",
            "rules",
            "replay",
            str(recording),
            "--rules",
            str(rules),
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_bag_of_another_writer_replays_through_rules(tmp_path: Path) -> None:
    levels = [50.0, 30.0, 19.0, 18.0, 17.0, 22.0, 24.0, 26.0, 27.0, 28.0]
    recording = battery_recording(tmp_path / "battery.mcap", levels)
    rules = tmp_path / "robot.layers"
    rules.write_text(BATTERY_RULES, encoding="utf-8")
    done = replay(recording, rules, "--json")
    assert done.returncode == 0, done.stderr
    switches = json.loads(done.stdout)["switches"]
    # Below 20 from 1.0 s on: held 1 s, so at the manager's first tick from 2.0 s. Back
    # above 25 (20 + the hysteresis) from 3.5 s on: held 1 s, so at 4.5 s.
    assert [(s["time"], s["active"], s["requester"]) for s in switches] == [
        (2.0, ["LowBattery"], "rule Low"),
        (4.5, [], "rule Low"),
    ]
    # Changed rules, same recording: a lower threshold never fires.
    rules.write_text(BATTERY_RULES.replace("< 20", "< 10"), encoding="utf-8")
    done = replay(recording, rules)
    assert done.returncode == 0, done.stderr
    assert "0 switches by these rules" in done.stdout


def test_a_truncated_recording_names_the_file_and_the_byte(tmp_path: Path) -> None:
    whole = battery_recording(tmp_path / "whole.mcap", [float(p) for p in range(100)])
    cut = tmp_path / "cut.mcap"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError) as raised:
        list(read_recording(cut))
    assert str(raised.value).startswith(f"{cut}: byte ")
    assert "truncated" in str(raised.value)
    # Replayed up to the cut, with a warning naming the file, the byte and the truncation.
    rules = tmp_path / "robot.layers"
    rules.write_text(BATTERY_RULES, encoding="utf-8")
    done = replay(cut, rules, "--json")
    assert done.returncode == 0, done.stderr
    damage = json.loads(done.stdout)["truncated"]
    assert damage["file"] == str(cut) and 0 < damage["byte"] < len(data) // 2
    readable = list(read_recording(cut, truncated=lambda damage: None))
    assert damage["messages_before"] == len(readable)
    assert f"warning: {cut}: byte {damage['byte']}: " in done.stderr
    assert "truncated" in done.stderr and "contextros repair" in done.stderr


def test_a_file_that_is_not_mcap_is_a_clear_error(tmp_path: Path) -> None:
    text = tmp_path / "notes.mcap"
    text.write_text("not a recording\n" * 10, encoding="utf-8")
    with pytest.raises(RecordingError, match=r"notes.mcap: byte \d+: not an MCAP file"):
        list(read_recording(text))
    with pytest.raises(RecordingError, match="cannot open the recording"):
        list(read_recording(tmp_path / "missing.mcap"))


def test_messages_of_unknown_types_are_skipped_with_one_note(tmp_path: Path) -> None:
    path = tmp_path / "mixed.mcap"
    with path.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="", library="test")
        json_schema = writer.register_schema("Pose", "jsonschema", b"{}")
        json_channel = writer.register_channel("/pose", "json", json_schema)
        ros_schema = writer.register_schema(
            "std_msgs/msg/Bool", "ros2msg", message_definition("std_msgs/msg/Bool").encode()
        )
        ros_channel = writer.register_channel("/dock", "cdr", ros_schema)
        for index in range(3):
            writer.add_message(json_channel, index, b'{"x": 1}', index)
        writer.add_message(ros_channel, 5, b"\x00\x01\x00\x00\x01", 5)  # CDR header, True
        writer.finish()
    notes: list[str] = []
    messages = list(read_recording(path, note=notes.append))
    assert [(m.topic, m.message.data) for m in messages] == [("/dock", True)]
    assert len(notes) == 1 and "Pose (json encoding, on /pose) skipped" in notes[0]


def test_a_message_that_does_not_match_its_schema_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.mcap"
    with path.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema(
            "sensor_msgs/msg/NavSatFix",
            "ros2msg",
            message_definition("sensor_msgs/msg/NavSatFix").encode(),
        )
        channel = writer.register_channel("/fix", "cdr", schema)
        writer.add_message(channel, 1, b"\x00\x01\x00\x00\x01\x00", 1)  # cut short
        writer.finish()
    with pytest.raises(
        RecordingError, match=r"message 1 on /fix does not decode as sensor_msgs/msg/NavSatFix"
    ):
        list(read_recording(path))


def test_any_cut_or_damage_is_a_recording_error_never_another_exception(tmp_path: Path) -> None:
    whole = battery_recording(tmp_path / "whole.mcap", [float(p) for p in range(60)]).read_bytes()
    damaged = tmp_path / "damaged.mcap"
    variants = [whole[:cut] for cut in range(0, len(whole), 53)]
    variants += [
        whole[:at] + bytes(b ^ 0x5A for b in whole[at : at + 16]) + whole[at + 16 :]
        for at in range(0, len(whole) - 16, 211)
    ]
    for variant in variants:
        damaged.write_bytes(variant)
        try:
            list(read_recording(damaged))
        except RecordingError as error:
            assert str(error).startswith(f"{damaged}: byte "), error
