"""Ordinary rclpy nodes that know nothing of ContextROS, for the layers-drive-ROS tests.

`/base` has a parameter `max_speed` (double, 1.0) and refuses values above 5.0; the
lifecycle node `/propeller` activates unless its parameter `refuse_activation` is true.
Prints one JSON line per event (`ready`, `parameter`, `transition`, `activating`).
`--slow-set S`: each parameter change of `/base` takes S seconds; `--slow-activate S`: so
does `/propeller`'s activation (the node answers nothing meanwhile, as a single-threaded
driver busy in `on_activate`).
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.node import Node

from contextros.ros import spin_nodes


def emit(event: str, **fields: object) -> None:
    print(json.dumps({"event": event, **fields}), flush=True)


class Base(Node):
    def __init__(self, slow_set: float = 0.0) -> None:
        super().__init__("base")
        self.slow_set = slow_set
        self.declare_parameter("max_speed", 1.0)
        self.add_on_set_parameters_callback(self.check)

    def check(self, parameters: list[Any]) -> SetParametersResult:
        time.sleep(self.slow_set)
        for parameter in parameters:
            if parameter.name == "max_speed" and parameter.value > 5.0:
                return SetParametersResult(successful=False, reason="above 5.0 m/s is unsafe")
        for parameter in parameters:
            emit("parameter", name=parameter.name, value=parameter.value)
        return SetParametersResult(successful=True)


class Propeller(LifecycleNode):
    def __init__(self, slow_activate: float = 0.0) -> None:
        super().__init__("propeller")
        self.slow_activate = slow_activate
        self.declare_parameter("refuse_activation", False)

    def on_configure(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", to="inactive", via="configure")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: Any) -> TransitionCallbackReturn:
        emit("activating")
        time.sleep(self.slow_activate)
        if self.get_parameter("refuse_activation").value:
            emit("transition", to="refused", via="activate")
            return TransitionCallbackReturn.FAILURE
        emit("transition", to="active", via="activate")
        return super().on_activate(state)

    def on_deactivate(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", to="inactive", via="deactivate")
        return super().on_deactivate(state)

    def on_cleanup(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", to="unconfigured", via="cleanup")
        return TransitionCallbackReturn.SUCCESS


def seconds(option: str) -> float:
    return float(sys.argv[sys.argv.index(option) + 1]) if option in sys.argv else 0.0


def main() -> None:
    rclpy.init(args=sys.argv)
    nodes: list[Node] = [Base(seconds("--slow-set")), Propeller(seconds("--slow-activate"))]
    emit("ready")
    spin_nodes(nodes)
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
