"""Rules and the plans of layers that drive ROS are pure: importing them loads no ROS."""

from __future__ import annotations

import subprocess
import sys


def test_rules_and_bindings_import_without_ros() -> None:
    probe = (
        "import sys, contextros.rules, contextros.bindings, contextros.language.rules;"
        "ros = ('rclpy', 'rcl_interfaces', 'lifecycle_msgs', 'sensor_msgs',"
        " 'contextros_interfaces');"
        "loaded = [m for m in sys.modules if m.split('.')[0] in ros "
        "or m.startswith('contextros.ros')]"
        ";assert not loaded, loaded"
    )
    subprocess.run([sys.executable, "-c", probe], check=True)
