"""The propeller driver: a lifecycle node, active only in flight.

An ordinary rclpy `LifecycleNode`: the Layer manager moves it with the standard lifecycle
services (`lifecycle PropellersOn: drivers/propeller active` in rescue.layers, a mode
Flight implies). The demo launches it in the sub-namespace drivers/ of the robot
(`--ros-args -r __ns:=/rescue1/drivers`).
"""

from __future__ import annotations

import sys
from typing import Any

import rclpy
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn

from contextros.ros import spin_nodes


class Propeller(LifecycleNode):
    def __init__(self) -> None:
        super().__init__("propeller")

    def on_configure(self, state: Any) -> TransitionCallbackReturn:
        print("propellers configured (resting)", flush=True)
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: Any) -> TransitionCallbackReturn:
        print("propellers spinning", flush=True)
        return super().on_activate(state)

    def on_deactivate(self, state: Any) -> TransitionCallbackReturn:
        print("propellers stopped", flush=True)
        return super().on_deactivate(state)


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([Propeller()])


if __name__ == "__main__":
    main()
