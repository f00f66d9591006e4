"""`contextros record` against real publishers: what it writes reads back as sent."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from rclpy.node import Node
from sensor_msgs.msg import BatteryState

from contextros.recording import read_recording
from contextros.ros import LayerClient


def record(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "contextros", "record", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_a_rules_topic_is_recorded_once_it_appears(client: LayerClient, tmp_path: Path) -> None:
    rules = tmp_path / "robot.layers"
    rules.write_text("rule Low: Night while battery.percentage < 20\n", encoding="utf-8")
    output = tmp_path / "run.mcap"
    recorder = record(str(output), "--rules", str(rules), "--duration", "4")
    node = Node("recorded_battery")
    publisher = node.create_publisher(BatteryState, "battery", 10)
    try:
        started = time.monotonic()
        sent = 0
        while recorder.poll() is None and time.monotonic() - started < 30:
            publisher.publish(BatteryState(percentage=float(sent)))
            sent += 1
            time.sleep(0.05)
        out, err = recorder.communicate(timeout=30)
    finally:
        node.destroy_node()
    assert recorder.returncode == 0, err
    assert f"to {output} (/battery: " in out, out
    values = [m.message.percentage for m in read_recording(output) if m.topic == "/battery"]
    assert values, "nothing recorded on /battery"
    # The first messages go by while the recorder discovers the topic; then every one, in order.
    assert values == [float(v) for v in range(int(values[0]), int(values[0]) + len(values))]
    types = {m.topic: m.type_name for m in read_recording(output)}
    assert types["/battery"] == "sensor_msgs/msg/BatteryState"


def test_a_bad_topic_name_is_refused_before_any_file_is_written(tmp_path: Path) -> None:
    output = tmp_path / "run.mcap"
    done = record(str(output), "--topic", "not a topic", "--duration", "1")
    _, err = done.communicate(timeout=60)
    assert done.returncode == 2
    assert "contextros record: topic 'not a topic': topic name must not contain" in err
    assert not output.exists()
