"""The greeting application with ContextROS: the city is a layer, chosen by the Layer manager.

Run: `python -m examples.greeting.context_node` next to a Layer manager, then
`contextros activate Tokyo`; it greets every second once a city is active.
"""

from __future__ import annotations

import sys
from datetime import datetime, timezone
from pathlib import Path

import rclpy
from std_msgs.msg import String

from contextros import active_layers, load
from contextros.ros import ContextNode, spin_nodes

greeting = load(Path(__file__).with_name("greeting.layers"))


class GreetingNode(ContextNode):
    def __init__(self) -> None:
        super().__init__("greeting", layers=greeting.__layers__)
        self.publisher = self.create_publisher(String, "greeting", 10)
        self.timer = self.create_timer(1.0, self.greet)

    def greet(self, now: datetime | None = None) -> None:
        if not active_layers():  # no city yet: nothing to say
            return
        local = (now or datetime.now(timezone.utc)).astimezone(greeting.zone())
        part_of_day = 0 if 5 <= local.hour < 12 else 1 if 12 <= local.hour < 18 else 2
        line = f"{local:%H:%M} {local.tzname()} {greeting.words(part_of_day)}"
        self.publisher.publish(String(data=line))
        print(line, flush=True)


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([GreetingNode()])  # ends quietly on Ctrl-C, after telling the manager


if __name__ == "__main__":
    main()
