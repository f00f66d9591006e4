"""The mobility node: moves the way the active layers say (a context node, rescue.layers).

Prints its locomotion after every state the Layer manager sends.
"""

from __future__ import annotations

import sys
from pathlib import Path

import rclpy

from contextros import load
from contextros.protocol import LayerState
from contextros.ros import ContextNode, spin_nodes

rescue = load(Path(__file__).with_name("rescue.layers"))


class MobilityNode(ContextNode):
    def __init__(self) -> None:
        super().__init__("mobility", layers=rescue.__layers__)
        self.context_participant.add_listener(self.on_state)

    def on_state(self, state: LayerState) -> None:
        layers = ", ".join(state.active) or "none"
        print(f"[{layers}] locomotion: {rescue.locomotion()}", flush=True)


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([MobilityNode()])


if __name__ == "__main__":
    main()
