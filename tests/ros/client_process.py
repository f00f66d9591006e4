"""A client that fires activation commands as fast as the manager answers them.

Prints one JSON line per answer (`result` with epoch, success and active layers) and a
final `done`. `--sync` sends synchronous commands.
`--layers A,B` alternates between activating A and activating B (one group, so each
command replaces the other); `--toggle L` alternates activating and deactivating L.
"""

from __future__ import annotations

import argparse
import json
import sys

import rclpy
from rclpy.node import Node
from rclpy.utilities import remove_ros_args

from contextros.ros import LayerClient


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", required=True)
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--layers", default="")
    parser.add_argument("--toggle", default="")
    parser.add_argument("--sync", action="store_true", help="synchronous commands")
    args = parser.parse_args(remove_ros_args(sys.argv)[1:])
    rclpy.init(args=sys.argv)
    node = Node(args.name)
    client = LayerClient(node, requester=args.name)
    client.wait_for_manager(30.0)  # discovery takes long when the machine is loaded
    alternatives = [name for name in args.layers.split(",") if name]
    for index in range(args.count):
        if alternatives:
            on, off = [alternatives[index % len(alternatives)]], []
        else:
            on, off = ([args.toggle], []) if index % 2 == 0 else ([], [args.toggle])
        result = client.request(
            on, off, reason=f"{args.name} #{index}", synchronous=args.sync, timeout=10.0
        )
        line = {
            "event": "result",
            "epoch": result.epoch,
            "success": result.success,
            "active": list(result.active),
        }
        print(json.dumps(line | {"message": result.message}), flush=True)
    print(json.dumps({"event": "done"}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
