"""The greeting application's Python node, as a user outside the clone writes it: layers from
the installed contextros, following the Layer manager (run by tests/install)."""

import sys

import rclpy

from contextros import Layer, active_layers, layered, subscribe
from contextros.ros import ContextNode, spin_nodes

Tokyo = Layer("Tokyo", group="city")
London = Layer("London", group="city")


@layered
def greeting() -> str:
    return "hello"


@greeting.partial(Tokyo)
def greeting() -> str:
    return "konnichiwa"


@greeting.partial(London)
def greeting() -> str:
    return "good morning"


def report(_event: object) -> None:
    layers = ",".join(layer.name for layer in active_layers())
    print(f"[{layers}]: {greeting()}", flush=True)


def main() -> None:
    with rclpy.init(args=sys.argv):
        subscribe(report)
        node = ContextNode("greeter_py")
        print("ready", flush=True)
        spin_nodes([node])


if __name__ == "__main__":
    main()
