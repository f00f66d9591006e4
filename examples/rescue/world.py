"""The simulated disaster: the battery level and the terrain under the robot, at 10 Hz.

Publishes `battery` (sensor_msgs/BatteryState) and `terrain` (std_msgs/String: road,
flooded) through a scripted mission, once the Layer manager's rules listen to both.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import BatteryState
from std_msgs.msg import String

RATE_HZ = 10.0
# (what happens, seconds, terrain, battery %)
MISSION = (
    ("the robot sets off on a road", 1.5, "road", 90.0),
    ("the road is flooded", 1.5, "flooded", 90.0),
    ("the battery runs down", 1.0, "flooded", 22.0),
    ("the battery is low", 1.5, "flooded", 15.0),
    ("the robot recharges", 1.5, "flooded", 30.0),
    ("the robot reaches a road again", 1.5, "road", 30.0),
)


class World(Node):
    def __init__(self) -> None:
        super().__init__("world")
        self.battery_pub = self.create_publisher(BatteryState, "battery", 10)
        self.terrain_pub = self.create_publisher(String, "terrain", 10)
        self.stage = -1
        self.stage_started = 0.0
        self.timer = self.create_timer(1.0 / RATE_HZ, self.wait_for_rules)

    def wait_for_rules(self) -> None:
        if self.battery_pub.get_subscription_count() and self.terrain_pub.get_subscription_count():
            self.timer.cancel()
            self.timer = self.create_timer(1.0 / RATE_HZ, self.tick)

    def tick(self) -> None:
        now = time.monotonic()
        if self.stage < 0 or now - self.stage_started >= MISSION[self.stage][1]:
            self.stage += 1
            self.stage_started = now
            if self.stage >= len(MISSION):
                print("mission complete", flush=True)
                self.timer.cancel()
                return
            print(MISSION[self.stage][0], flush=True)
        _, _, terrain, battery = MISSION[self.stage]
        self.terrain_pub.publish(String(data=terrain))
        self.battery_pub.publish(BatteryState(percentage=battery))


def main() -> None:
    try:
        with rclpy.init(args=sys.argv):
            rclpy.spin(World())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


if __name__ == "__main__":
    main()
