"""The context detector: decides indoors or outdoors from the GPS, and tells the Layer manager.

A GPS fix for `SETTLE_READINGS` readings in a row means Outdoor, no fix as long means Indoor
(one stray reading does not flip the robot). Each switch is one synchronous activation
command: it returns once every context node has applied it, with the time that took.

Run: `python -m examples.cleaner.context_detector [--nodes N]` (N: wait until N context
nodes have joined the manager before deciding anything; default 2).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import NavSatFix, NavSatStatus

from contextros import LayerError
from contextros.ros import LayerClient

SETTLE_READINGS = 3  # 0.15 s of the 20 Hz receiver
OTHER = {"Indoor": "Outdoor", "Outdoor": "Indoor"}


class ContextDetector(Node):
    def __init__(self) -> None:
        super().__init__("context_detector")
        self.client = LayerClient(self, requester="context_detector")
        self.announced = ""  # the context the manager was last told
        self.observed = "Indoor"  # the robot is switched on inside
        self.readings = SETTLE_READINGS  # in a row agreeing with `observed`
        self.create_subscription(NavSatFix, "gps/fix", self.on_gps, 10)

    def on_gps(self, msg: Any) -> None:
        seen = "Outdoor" if msg.status.status >= NavSatStatus.STATUS_FIX else "Indoor"
        if seen == self.observed:
            self.readings += 1
        else:
            self.observed, self.readings = seen, 1

    def wait_for_nodes(self, count: int, timeout: float = 20.0) -> None:
        """Until `count` context nodes joined and the manager has settled its first state
        (a command sent while it still recovers would wait for that, and look slow)."""
        self.client.wait_for_manager(timeout)
        deadline = time.monotonic() + timeout
        while True:
            registry = self.client.query()
            if len(registry.participants) >= count and not registry.recovering:
                return
            if time.monotonic() > deadline:
                raise TimeoutError(f"fewer than {count} context nodes joined in {timeout:g} s")
            time.sleep(0.1)

    def settled_context(self) -> str | None:
        """The context the sensors agree on, when it differs from what the manager knows."""
        if self.readings >= SETTLE_READINGS and self.observed != self.announced:
            return self.observed
        return None

    def switch_to(self, context: str) -> None:
        sent = time.monotonic()
        result = self.client.request(
            [context], [OTHER[context]], synchronous=True, timeout=2.0, reason="GPS"
        )
        round_trip = (time.monotonic() - sent) * 1000
        if not result.success:
            print(f"the manager did not switch to {context}: {result.message}", flush=True)
            time.sleep(0.2)  # then try again, without flooding the manager
            return
        self.announced = context
        print(
            f"switched to {context}: {len(result.acknowledged)} nodes applied it in "
            f"{result.elapsed * 1000:.1f} ms (manager), {round_trip:.1f} ms round trip",
            flush=True,
        )


def main() -> None:
    rclpy.init(args=sys.argv)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, default=2, help="context nodes to wait for")
    args = parser.parse_args(remove_ros_args(sys.argv)[1:])
    node = ContextDetector()
    try:
        node.wait_for_nodes(args.nodes)
        print(f"ready: the manager and {args.nodes} context nodes are up", flush=True)
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.05)
            context = node.settled_context()
            if context is not None:
                node.switch_to(context)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (LayerError, TimeoutError) as error:
        print(f"context detector: {error}", file=sys.stderr, flush=True)
        sys.exit(1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
