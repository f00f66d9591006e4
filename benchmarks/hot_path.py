"""The manager's hot path, piece by piece (issue 16): a status read and written through
rclpy's messages or as bytes (`contextros.ros.status_wire`), and the CPU of one wake-up of
`WaitLoop` against rclpy's `SingleThreadedExecutor` (a node with a 1 kHz timer, 3 s each).

Run with `python -m benchmarks.hot_path`; it prints a table and writes nothing. With
`--wake-up-only` it measures the wake-ups alone, for code without status_wire (the code
before: `PYTHONPATH=benchmarks/before_site:TREE/src python benchmarks/hot_path.py
--wake-up-only`).
"""

from __future__ import annotations

import os
import sys
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

CALLS = 20_000
HOT_PATH_DOMAIN_ID = 87
LOCATION_LAYERS = Path(__file__).resolve().parent.parent / "examples/cleaner/location.layers"
REPEATS = 5


def _microseconds(function: Callable[[], Any]) -> float:
    return min(timeit.repeat(function, number=CALLS, repeat=REPEATS)) / CALLS * 1e6


def status_rows() -> list[tuple[str, float]]:
    from contextros_interfaces.msg import ParticipantStatus
    from rclpy.serialization import deserialize_message, serialize_message

    from contextros.protocol import LayerDeclaration, ParticipantReport
    from contextros.ros.messages import report_from_msg, report_to_msg
    from contextros.ros.status_wire import StatusDecoder, StatusEncoder

    place = "place"
    report = ParticipantReport(
        node="/robot/cleaner_01",
        incarnation="4711-0b5e2c",
        layers=(
            LayerDeclaration("Indoor", excludes=frozenset({"Outdoor"}), group=place),
            LayerDeclaration("Outdoor", excludes=frozenset({"Indoor"}), group=place),
        ),
        applied_epoch=12,
        applied_manager_id="4242-1a2b",
        active=("Indoor",),
    )
    now = time.time()
    data = serialize_message(report_to_msg(report, now))
    decoder, encoder = StatusDecoder(), StatusEncoder()
    assert decoder.decode(data) == report_from_msg(deserialize_message(data, ParticipantStatus))
    return [
        (
            "read a status: rclpy's message, then report_from_msg",
            _microseconds(lambda: report_from_msg(deserialize_message(data, ParticipantStatus))),
        ),
        ("read a status: StatusDecoder", _microseconds(lambda: decoder.decode(data))),
        (
            "write a status: report_to_msg, then rclpy's serialization",
            _microseconds(lambda: serialize_message(report_to_msg(report, now))),
        ),
        ("write a status: StatusEncoder", _microseconds(lambda: encoder.encode(report, now))),
    ]


def wake_up_rows(seconds: float = 3.0) -> list[tuple[str, float]]:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from contextros.language import load
    from contextros.ros import ContextNode
    from contextros.ros.wait_loop import WaitLoop

    # A domain of its own, on this host only: its context nodes must meet no manager.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    rclpy.init(domain_id=HOT_PATH_DOMAIN_ID)
    rows = []
    try:
        node = Node("hot_path_wake_up", start_parameter_services=False)
        ticks = [0]
        node.create_timer(0.001, lambda: ticks.__setitem__(0, ticks[0] + 1))
        # A worker of the activation benchmark: 8 context nodes, a participant each (their
        # parameter services, subscriptions, timers and QoS event handlers: 180 entities).
        layers = load(LOCATION_LAYERS).__layers__
        workers = [
            ContextNode(f"hot_path_{index}", layers=layers, share_participant=False)
            for index in range(8)
        ]
        cases = [("a timer's wake-up", [node]), ("with 8 context nodes", [node, *workers])]
        for case, nodes in cases:
            for label in ("WaitLoop", "SingleThreadedExecutor", "WaitLoop"):
                if label == "WaitLoop":
                    loop: Any = WaitLoop(nodes)
                else:
                    loop = SingleThreadedExecutor()
                    for member in nodes:
                        loop.add_node(member)
                ticks[0] = 0
                cpu, started = time.process_time(), time.monotonic()
                while time.monotonic() - started < seconds:
                    loop.spin_once(0.1)
                used = time.process_time() - cpu
                rows.append((f"{case}: {label}", used / max(ticks[0], 1) * 1e6))
                if label == "WaitLoop":
                    loop.shutdown()
                else:
                    for member in nodes:
                        loop.remove_node(member)
        for member in [*workers, node]:
            member.destroy_node()
    finally:
        rclpy.try_shutdown()
    return rows


def main(argv: list[str]) -> None:
    rows = [] if "--wake-up-only" in argv else status_rows()
    print("| case | µs (CPU) |")
    print("|---|---:|")
    for case, value in rows + wake_up_rows():
        print(f"| {case} | {value:.1f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
