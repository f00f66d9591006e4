"""The floor under the manager's status path (issue 26, item 4): the CPU a process spends on
receiving one status through rclpy and the rmw when its callback does nothing, spun by
`WaitLoop` as the manager is. One process publishes `ParticipantStatus` messages in bursts;
this one takes them raw and reads its own CPU time (every thread, from schedstat, ns).

    python -m benchmarks.status_delivery 1 0.01    # one status every 10 ms
    python -m benchmarks.status_delivery 16 0.1    # 16 back to back every 100 ms

Run it with its own ROS_DOMAIN_ID (and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

TOPIC = "/contextros_bench/status_delivery"


def _cpu_seconds() -> float:
    tasks = Path(f"/proc/{os.getpid()}/task").iterdir()
    return sum(int((task / "schedstat").read_text().split()[0]) for task in tasks) / 1e9


def _publish(burst: int, gap: float) -> None:
    import rclpy
    from contextros_interfaces.msg import ParticipantStatus

    from contextros.ros.topics import STATUS_QOS

    rclpy.init()
    node = rclpy.create_node("status_delivery_publisher")
    publisher = node.create_publisher(ParticipantStatus, TOPIC, STATUS_QOS)
    message = ParticipantStatus(node="/robot/node1", incarnation="1")
    time.sleep(2.0)  # discovery
    end = time.monotonic() + 8.0
    while time.monotonic() < end:
        for _ in range(burst):
            publisher.publish(message)
        time.sleep(gap)


def _receive() -> str:
    import rclpy
    from contextros_interfaces.msg import ParticipantStatus

    from contextros.ros.topics import STATUS_QOS
    from contextros.ros.wait_loop import WaitLoop

    rclpy.init()
    node = rclpy.create_node("status_delivery_receiver")
    received = [0]

    def count(_: bytes) -> None:
        received[0] += 1

    node.create_subscription(ParticipantStatus, TOPIC, count, STATUS_QOS, raw=True)
    loop = WaitLoop([node])
    start = time.monotonic()
    marks: list[tuple[int, float]] = []
    while time.monotonic() - start < 9.0:
        loop.spin_once(0.1)
        elapsed = time.monotonic() - start
        if elapsed > (3.0 if not marks else 8.0) and len(marks) < 2:
            marks.append((received[0], _cpu_seconds()))
    (count0, cpu0), (count1, cpu1) = marks
    statuses = count1 - count0
    return f"{statuses} statuses, {(cpu1 - cpu0) / max(1, statuses) * 1e6:.1f} us CPU each"


def main(argv: list[str]) -> int:
    if argv[:1] == ["publish"]:
        _publish(int(argv[1]), float(argv[2]))
        return 0
    burst, gap = (int(argv[0]), float(argv[1])) if argv else (1, 0.01)
    publisher = subprocess.Popen(
        [sys.executable, "-m", "benchmarks.status_delivery", "publish", str(burst), str(gap)],
        cwd=Path(__file__).resolve().parent.parent,
    )
    try:
        print(f"bursts of {burst} every {gap:g} s: {_receive()}")
    finally:
        publisher.wait(15)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
