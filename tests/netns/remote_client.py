"""An activation client in its own process (run inside a namespace by the two-host tests).

Reads one JSON command per line on stdin and prints one JSON line per answer:
`{"op": "request", "activate": [...], "deactivate": [...], "synchronous": true,
"timeout": 5, "expect_count": 2}` -> `{"event": "result", ...}` with the client's round
trip in `trip`; `{"op": "query"}` -> `{"event": "registry", ...}`.
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from rclpy.node import Node

from contextros.errors import LayerError
from contextros.ros import LayerClient


def main() -> int:
    rclpy.init()
    node = Node(f"remote_client_{time.monotonic_ns() % 100000}")
    client = LayerClient(node, requester="remote-client")
    print(json.dumps({"event": "ready"}), flush=True)
    for line in sys.stdin:
        command = json.loads(line)
        started = time.monotonic()
        try:
            if command.pop("op") == "query":
                r = client.query(timeout=5.0)
                answer = {
                    "event": "registry",
                    "epoch": r.epoch,
                    "participants": [p.node for p in r.participants],
                    "dropped": list(r.dropped),
                    "recovering": r.recovering,
                }
            else:
                activate = command.pop("activate", [])
                deactivate = command.pop("deactivate", [])
                result = client.request(activate, deactivate, **command)
                answer = {"event": "result", **result.__dict__}
        except LayerError as error:
            answer = {"event": "error", "message": str(error)}
        answer["trip"] = time.monotonic() - started
        print(json.dumps(answer, default=list), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
