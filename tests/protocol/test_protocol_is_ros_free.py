"""The protocol is pure: importing it (and the CLI's ROS commands module) loads no ROS."""

from __future__ import annotations

import subprocess
import sys


def test_protocol_and_cli_import_without_rclpy() -> None:
    probe = (
        "import sys, contextros.protocol, contextros.cli;"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'contextros_interfaces', 'contextros'))"
        ";assert not [m for m in loaded if not m.startswith('contextros') or "
        "m.startswith(('contextros_interfaces', 'contextros.ros'))], loaded"
    )
    subprocess.run([sys.executable, "-c", probe], check=True)
