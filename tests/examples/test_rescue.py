"""The rescue robot (issue 11, part 5), end to end in real processes: rules from the battery
and terrain topics, a parameter-bound layer, a lifecycle node active only in flight, the
whole robot in a namespace and the propeller driver in a sub-namespace."""

from __future__ import annotations

import subprocess
import sys

import pytest
from examples.launch import REPOSITORY, ros_environment


@pytest.mark.ros
def test_the_terrain_and_the_battery_drive_the_robot(domain_id: int) -> None:
    demo = subprocess.run(
        [sys.executable, "-m", "examples.rescue.demo"],
        cwd=REPOSITORY,
        env=ros_environment(domain_id),
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert demo.returncode == 0, demo.stdout + demo.stderr
    out = demo.stdout
    summary = out[out.index("summary:") :]
    # Each mode of the robot with the modes of its parts it implies (issue 28).
    wheels, flight = "[PropellersOff, Wheels]", "[PropellersOn, Flight]"
    low = "[PropellersOff, Wheels, SlowDrive, LowBattery]"
    assert f"{wheels} -> {flight} -> {wheels} -> {low} -> {wheels} -> {flight} -> {wheels}" in (
        summary
    )
    assert "max_speed   1.5 -> 0.3 -> 1.5 m/s" in summary
    assert summary.count("propellers spinning") == 2
    # The rules decided, in the robot's namespace; the low battery slowed the robot down.
    assert "rules read /rescue1/battery (sensor_msgs/msg/BatteryState)" in out
    assert "rule Battery switched to LowBattery" in out
    assert "driving on wheels, slowly to save the battery" in out
