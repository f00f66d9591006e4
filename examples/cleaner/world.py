"""The simulated world: the robot drives out of a building, turns and comes back.

Publishes what the robot's sensors would see, at 20 Hz: the gyro (`imu`, sensor_msgs/Imu),
the wheel speed (`wheel_speed`, geometry_msgs/TwistStamped) and the GPS receiver
(`gps/fix`, sensor_msgs/NavSatFix), which has no fix inside the building and a fix once the
robot is clear of its wall. Prints each stage of the drive; after the route it stands still.
The drive starts once the robot's localization and the manager's context rule listen (discovery
takes a moment), so they see all of it.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import rclpy
from geometry_msgs.msg import TwistStamped
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

from examples.cleaner.gps_frame import to_fix

WALL_X = 3.0  # the building is x < WALL_X
GPS_CLEARANCE = 0.5  # the receiver gets a fix this far outside the wall
RATE_HZ = 20.0
DISCOVERY_MARGIN = 0.3  # seconds between our publisher matching and trusting the match


@dataclass(frozen=True)
class Leg:
    """A stretch of the route: drive at `speed` m/s and turn at `yaw_rate` rad/s."""

    description: str
    duration: float
    speed: float
    yaw_rate: float


ROUTE = (
    Leg("cleans its way to the door", 1.5, 2.0, 0.0),
    Leg("drives out into the yard", 3.0, 2.0, 0.0),
    Leg("turns around", 1.0, 0.0, math.pi),
    Leg("drives back into the building", 3.5, 2.0, 0.0),
)


class WorldNode(Node):
    def __init__(self) -> None:
        super().__init__("world")
        self.imu_pub = self.create_publisher(Imu, "imu", 10)
        self.wheel_pub = self.create_publisher(TwistStamped, "wheel_speed", 10)
        self.gps_pub = self.create_publisher(NavSatFix, "gps/fix", 10)
        self.x = self.y = self.heading = 0.0
        self.leg_index = -1
        self.leg_started = self.last_tick = 0.0
        self.indoors = True
        self.timer = self.create_timer(1.0 / RATE_HZ, self.wait_for_listeners)
        self.listeners_since: float | None = None

    def wait_for_listeners(self) -> None:
        # Both the localization and the manager's rule read the GPS; only the former the gyro.
        heard = self.gps_pub.get_subscription_count() >= 2 and self.imu_pub.get_subscription_count()
        now = time.monotonic()
        if not heard:
            self.listeners_since = None
            return
        self.listeners_since = self.listeners_since or now
        if now - self.listeners_since < DISCOVERY_MARGIN:  # let the other side match too
            return
        self.timer.cancel()
        self.leg_started = self.last_tick = now
        self.timer = self.create_timer(1.0 / RATE_HZ, self.tick)
        self.say(f"the robot starts inside the building at x = {self.x:.1f} m")

    def say(self, text: str) -> None:
        print(text, flush=True)

    def current_leg(self, now: float) -> Leg | None:
        if self.leg_index < 0 or now - self.leg_started >= ROUTE[self.leg_index].duration:
            self.leg_index += 1
            self.leg_started = now
            if self.leg_index >= len(ROUTE):
                self.timer.cancel()
                self.timer = self.create_timer(1.0 / RATE_HZ, self.stand_still)
                self.say("route complete: the robot stands still inside")
                return None
            self.say(f"the robot {ROUTE[self.leg_index].description}")
        return ROUTE[self.leg_index]

    def tick(self) -> None:
        now = time.monotonic()
        dt, self.last_tick = now - self.last_tick, now
        leg = self.current_leg(now)
        if leg is None:
            return
        self.heading += leg.yaw_rate * dt
        self.x += leg.speed * math.cos(self.heading) * dt
        self.y += leg.speed * math.sin(self.heading) * dt
        if self.indoors != (self.x < WALL_X):
            self.indoors = self.x < WALL_X
            where = "enters the building" if self.indoors else "leaves the building"
            self.say(f"the robot {where} at x = {self.x:.1f} m")
        self.publish(leg.speed, leg.yaw_rate)

    def stand_still(self) -> None:
        self.publish(0.0, 0.0)

    def publish(self, speed: float, yaw_rate: float) -> None:
        stamp = self.get_clock().now().to_msg()
        imu = Imu()
        imu.header.stamp = stamp
        imu.angular_velocity.z = yaw_rate
        self.imu_pub.publish(imu)
        wheels = TwistStamped()
        wheels.header.stamp = stamp
        wheels.twist.linear.x = speed
        self.wheel_pub.publish(wheels)
        fix = NavSatFix()
        fix.header.stamp = stamp
        if self.x >= WALL_X + GPS_CLEARANCE:
            fix.status.status = NavSatStatus.STATUS_FIX
            fix.latitude, fix.longitude = to_fix(self.x, self.y)
        else:
            fix.status.status = NavSatStatus.STATUS_NO_FIX
            fix.latitude = fix.longitude = math.nan
        self.gps_pub.publish(fix)


def main() -> None:
    try:
        with rclpy.init(args=sys.argv):
            rclpy.spin(WorldNode())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


if __name__ == "__main__":
    main()
