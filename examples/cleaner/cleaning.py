"""The cleaning node: cleans the way the active location layer says (wiping or vacuuming).

Publishes the method in use on `cleaning/method` (std_msgs/String) at 10 Hz and prints
when it changes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import rclpy
from std_msgs.msg import String

from contextros import active_layers, load
from contextros.ros import ContextNode, spin_nodes
from examples.cleaner.narration import report_applied

location = load(Path(__file__).with_name("location.layers"))


class CleaningNode(ContextNode):
    def __init__(self) -> None:
        super().__init__("cleaning", layers=location.__layers__)
        self.context_participant.add_listener(report_applied)
        self.method = "nothing"
        self.method_pub = self.create_publisher(String, "cleaning/method", 10)
        self.timer = self.create_timer(0.1, self.clean)

    def clean(self) -> None:
        if not active_layers():  # the manager has not said where we are yet
            return
        method = location.cleaning_method()
        if method != self.method:
            print(f"cleaning by {method} now", flush=True)
            self.method = method
        self.method_pub.publish(String(data=method))


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([CleaningNode()])  # ends quietly on Ctrl-C, after telling the manager


if __name__ == "__main__":
    main()
