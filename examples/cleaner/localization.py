"""The localization node: estimates the robot's pose the way the active location layer says.

Indoor: dead reckoning from the gyro and the wheels; Outdoor: the GPS fix (`location.layers`).
Publishes `pose` (geometry_msgs/PoseStamped) on every gyro reading and prints when the
source of its estimate changes.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped, TwistStamped
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

from contextros import active_layers, load
from contextros.ros import ContextNode, spin_nodes
from examples.cleaner.gps_frame import to_local
from examples.cleaner.narration import report_applied

location = load(Path(__file__).with_name("location.layers"))


class LocalizationNode(ContextNode):
    def __init__(self) -> None:
        super().__init__("localization", layers=location.__layers__)
        self.context_participant.add_listener(report_applied)
        self.pose = location.Pose(0.0, 0.0, 0.0, "none")
        self.speed = 0.0
        self.gps: tuple[float, float] | None = None
        self.last_stamp: float | None = None
        self.pose_pub = self.create_publisher(PoseStamped, "pose", 10)
        self.create_subscription(TwistStamped, "wheel_speed", self.on_wheels, 10)
        self.create_subscription(NavSatFix, "gps/fix", self.on_gps, 10)
        self.create_subscription(Imu, "imu", self.on_gyro, 10)

    def on_wheels(self, msg: Any) -> None:
        self.speed = msg.twist.linear.x

    def on_gps(self, msg: Any) -> None:
        has_fix = msg.status.status >= NavSatStatus.STATUS_FIX
        self.gps = to_local(msg.latitude, msg.longitude) if has_fix else None

    def on_gyro(self, msg: Any) -> None:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        dt = 0.0 if self.last_stamp is None else stamp - self.last_stamp
        self.last_stamp = stamp
        if not active_layers():  # the manager has not said where we are yet
            return
        sensors = location.Sensors(msg.angular_velocity.z, self.speed, self.gps)
        pose = location.estimate_pose(self.pose, sensors, dt)
        self.gps = None  # each fix is used once
        if pose.source != self.pose.source:
            print(f"position from the {pose.source} now: ({pose.x:.1f}, {pose.y:.1f})", flush=True)
        self.pose = pose
        self.publish(pose, msg.header.stamp)

    def publish(self, pose: Any, stamp: Any) -> None:
        msg = PoseStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = "map"
        msg.pose.position.x, msg.pose.position.y = pose.x, pose.y
        msg.pose.orientation.z = math.sin(pose.heading / 2)
        msg.pose.orientation.w = math.cos(pose.heading / 2)
        self.pose_pub.publish(msg)


def main() -> None:
    with rclpy.init(args=sys.argv):
        spin_nodes([LocalizationNode()])  # ends quietly on Ctrl-C, after telling the manager


if __name__ == "__main__":
    main()
