"""`topic` declarations with the interfaces installed here: `contextros check` finds a rule's
field errors without a running system, word for word what the manager reports at run time,
and the manager refuses a topic a real publisher sends with another type than declared."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from rclpy.node import Node
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.test_cli import contextros

CHECKED = """\
topic battery: sensor_msgs/msg/BatteryState
topic terrain: std_msgs/msg/String
topic odom: robot_nav_msgs/msg/Odometry
rule Low: Night while battery.percentage < 20 and battery.present
rule Bad: Dim while battery.percent < 20
rule Kind: Flight while terrain.data > 3
rule Far: Away while odom.pose.pose.position.x > 10
rule Dock: Docked while dock.data
"""


def heads(output: str) -> list[str]:
    """The first line of each diagnostic (the quote and the caret follow it)."""
    return [line for line in output.splitlines() if not line.startswith("    ")]


def test_check_reads_the_declared_types_from_the_installed_interfaces(tmp_path: Path) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(CHECKED, encoding="utf-8")
    done = contextros("check", str(path))
    assert done.returncode == 1, done.stdout + done.stderr
    assert heads(done.stdout) == [
        f"{path}:5:21: error: sensor_msgs/msg/BatteryState (the type of topic 'battery') has "
        "no field 'percent'",
        f"{path}:6:25: error: 'terrain.data' is a string field of std_msgs/msg/String: it "
        "cannot be compared with the number 3",
        f"{path}:7:22: note: rule Far's fields on topic 'odom' are checked at run time, when "
        "the Layer manager sees the topic's type: its declared type "
        "robot_nav_msgs/msg/Odometry (robot.layers:3) is not available here: message package "
        "'robot_nav_msgs' is not installed here: No module named 'robot_nav_msgs'",
        f"{path}:8:25: note: rule Dock's fields on topic 'dock' are checked at run time, when "
        "the Layer manager sees the topic's type: it has no declaration "
        "('topic dock: PACKAGE/msg/TYPE')",
    ]
    # Without the two wrong rules: a warning (terrain is read no more) and notes, exit 0.
    path.write_text("\n".join(CHECKED.splitlines()[:4] + CHECKED.splitlines()[6:]) + "\n")
    done = contextros("check", str(path))
    assert done.returncode == 0, done.stdout
    assert [line.split(": ")[1] for line in heads(done.stdout)] == ["warning", "note", "note"]


def test_the_installed_lookup_loads_message_packages_but_not_rclpy() -> None:
    probe = (
        "import sys\n"
        "from contextros.ros.message_types import installed_message_type\n"
        "lookup = installed_message_type('sensor_msgs/msg/BatteryState')\n"
        "assert lookup(('percentage',)) == 'number', lookup(('percentage',))\n"
        "assert lookup(('header', 'stamp', 'sec')) == 'number'\n"
        "assert lookup(('percent',)) is None\n"
        "assert 'sensor_msgs.msg' in sys.modules\n"
        "loaded = [m for m in sys.modules if m.split('.')[0] == 'rclpy']\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run([sys.executable, "-c", probe], check=True)


def manager_line(manager: Child, text: str, what: str, timeout: float = 15.0) -> str:
    found: list[str] = []

    def seen(_: object) -> bool:
        found[:] = [line for line in manager.lines if text in line]
        return bool(found)

    manager.wait_for(seen, timeout, what)
    return found[0]


def test_check_reports_a_field_as_the_manager_does_at_run_time(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(
        "topic battery: sensor_msgs/msg/BatteryState\nrule Bad: Night while battery.percent < 20\n",
        encoding="utf-8",
    )
    offline = heads(contextros("check", str(path)).stdout)
    assert len(offline) == 1 and ": error: " in offline[0], offline
    manager = processes.manager("--rules", str(path), "--ros-args", "-r", "__ns:=/offline")
    node = Node("battery", namespace="/offline")
    try:
        publisher = node.create_publisher(BatteryState, "battery", 10)
        publisher.publish(BatteryState(percentage=1.0))
        line = manager_line(manager, "has no field 'percent'", "the field error")
        assert line.endswith(offline[0]), (line, offline[0])
    finally:
        node.destroy_node()


def test_the_manager_refuses_a_topic_published_with_another_type_than_declared(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(
        "# the battery\n"
        "topic battery: sensor_msgs/msg/BatteryState\n"
        "rule Low: Night while battery.percentage < 20\n",
        encoding="utf-8",
    )
    manager = processes.manager("--rules", str(path), "--ros-args", "-r", "__ns:=/mismatch")
    node = Node("battery", namespace="/mismatch")
    try:
        wrong = node.create_publisher(Float32, "battery", 10)
        line = manager_line(manager, "is published as", "the type mismatch")
        assert line.endswith(
            f"{path}:2:16: error: topic /mismatch/battery is published as std_msgs/msg/Float32, "
            "but topic 'battery' is declared as sensor_msgs/msg/BatteryState: the rules "
            "reading it (Low) stay off"
        ), line
        assert "rules on /mismatch/battery stay off" in manager.output()
        assert "rules read /mismatch/battery" not in manager.output()
        shown = contextros("status", "--json", "--namespace", "/mismatch")
        assert shown.returncode == 0, shown.stderr
        (rule,) = json.loads(shown.stdout)["rules"]
        assert rule["value"] == "off", rule
        assert "is published as std_msgs/msg/Float32" in rule["error"], rule
        # The wrong publisher goes, one of the declared type comes: the rule runs.
        node.destroy_publisher(wrong)
        right = node.create_publisher(BatteryState, "battery", 10)
        manager_line(manager, "rules read /mismatch/battery (sensor_msgs/msg/BatteryState)", "bind")
        deadline = time.monotonic() + 10
        while "rule Low could not switch to Night" not in manager.output():
            assert time.monotonic() < deadline, manager.output()
            right.publish(BatteryState(percentage=5.0))  # no node implements Night: refused
            time.sleep(0.05)
    finally:
        node.destroy_node()
