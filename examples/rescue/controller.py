"""The motion controller: an ordinary rclpy node with a `max_speed` parameter.

It knows nothing of ContextROS: the Layer manager sets `max_speed` while SlowDrive is active
(`parameter SlowDrive: controller max_speed = 0.3` in rescue.layers; LowBattery implies
SlowDrive) and restores it after.
It refuses speeds above 3 m/s, as a real controller would validate its limits.
"""

from __future__ import annotations

import sys
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from contextros.ros import spin_nodes

LIMIT = 3.0


class Controller(Node):
    def __init__(self) -> None:
        super().__init__("controller")
        self.declare_parameter("max_speed", 1.5)
        self.add_on_set_parameters_callback(self.check)
        print(f"max_speed {self.get_parameter('max_speed').value} m/s", flush=True)

    def check(self, parameters: list[Any]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == "max_speed":
                if not 0.0 < parameter.value <= LIMIT:
                    return SetParametersResult(
                        successful=False, reason=f"max_speed must be in (0, {LIMIT}] m/s"
                    )
                print(f"max_speed {parameter.value} m/s", flush=True)
        return SetParametersResult(successful=True)


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([Controller()])


if __name__ == "__main__":
    main()
