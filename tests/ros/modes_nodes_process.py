"""The nodes of an imported system_modes model, for the import-modes test on real processes.

`modes_nodes_process.py NODES_JSON LAYERS...`: loads the layer files LAYERS (their layers
are implemented, and so announced to the manager, by one context node; with none, no context
node: only the manager's own layer files declare the layers) and starts one ordinary
rclpy lifecycle node per entry of NODES_JSON (`{"motors/front": {"rpm": 0}, ...}`: the node's
name, its namespace before the last `/`, and its parameters with their start values).
Prints one JSON line per event (`ready`, `parameter`, `transition`).
"""

from __future__ import annotations

import json
import sys
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.node import Node
from rclpy.utilities import remove_ros_args

from contextros.language import load
from contextros.ros import ContextNode, spin_nodes


def emit(event: str, **fields: object) -> None:
    print(json.dumps({"event": event, **fields}), flush=True)


class ModelNode(LifecycleNode):
    """A lifecycle node as a system_modes model expects one: parameters, states."""

    def __init__(self, full_name: str, parameters: dict[str, Any]) -> None:
        namespace, _, name = full_name.rpartition("/")
        super().__init__(name, namespace=f"/{namespace}" if namespace else "/")
        self.full_name = full_name
        for parameter, value in parameters.items():
            self.declare_parameter(parameter, value)
        self.add_on_set_parameters_callback(self.changed)

    def changed(self, parameters: list[Any]) -> SetParametersResult:
        for parameter in parameters:
            emit("parameter", node=self.full_name, name=parameter.name, value=parameter.value)
        return SetParametersResult(successful=True)

    def on_configure(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", node=self.full_name, to="inactive")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", node=self.full_name, to="active")
        return super().on_activate(state)

    def on_deactivate(self, state: Any) -> TransitionCallbackReturn:
        emit("transition", node=self.full_name, to="inactive")
        return super().on_deactivate(state)


def main() -> None:
    rclpy.init(args=sys.argv)
    arguments = remove_ros_args(sys.argv)
    for layers in arguments[2:]:
        load(layers)
    nodes: list[Node] = [ContextNode("modes_participant")] if arguments[2:] else []
    nodes += [ModelNode(name, values) for name, values in json.loads(arguments[1]).items()]
    emit("ready")
    spin_nodes(nodes)
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
