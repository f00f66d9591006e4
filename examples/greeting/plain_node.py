"""The greeting application as a good plain-rclpy node: the city is a validated parameter.

Run: `python -m examples.greeting.plain_node --ros-args -p city:=Tokyo`; it greets every
second, and the city can be changed at run time through the node's parameter service.
"""

from __future__ import annotations

import sys
from datetime import datetime, timedelta, timezone
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String

CITIES = ("Tokyo", "London")


class GreetingNode(Node):
    def __init__(self) -> None:
        super().__init__("greeting")
        self.add_on_set_parameters_callback(self.check_city)
        self.declare_parameter("city", "London")
        self.publisher = self.create_publisher(String, "greeting", 10)
        self.timer = self.create_timer(1.0, self.greet)

    def check_city(self, parameters: list[Parameter[Any]]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == "city" and parameter.value not in CITIES:
                reason = f"unknown city {parameter.value!r}; known: {', '.join(CITIES)}"
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def greet(self, now: datetime | None = None) -> None:
        city = self.get_parameter("city").value
        if city == "Tokyo":
            zone = timezone(timedelta(hours=9), "JST")
        else:
            zone = timezone(timedelta(0), "GMT")
        local = (now or datetime.now(timezone.utc)).astimezone(zone)
        part_of_day = 0 if 5 <= local.hour < 12 else 1 if 12 <= local.hour < 18 else 2
        if city == "Tokyo":
            words = ("おはようございます", "こんにちは", "こんばんは")[part_of_day]
        else:
            words = ("Good morning", "Good afternoon", "Good evening")[part_of_day]
        line = f"{local:%H:%M} {local.tzname()} {words}"
        self.publisher.publish(String(data=line))
        print(line, flush=True)


def main() -> None:
    try:
        with rclpy.init(args=sys.argv):
            rclpy.spin(GreetingNode())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


if __name__ == "__main__":
    main()
