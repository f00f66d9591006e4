"""A command's deadline with layers that drive ROS (parameters set one by one, each call may
take seconds): a command whose parameters were being set when its deadline passed is carried
through (refused then, ROS would go there and back); one waiting behind it is refused at its
deadline, saying what it waited for."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from contextros.ros import LayerClient
from tests.ros.processes import HERE, ProcessGroup
from tests.ros.system import LIVENESS, wait_for_manager, wait_registry
from tests.ros.test_ros_bindings import max_speed

SLOW_SET = 1.8  # seconds each parameter call of the base node takes (its calls may take 1 + 2 s)


def test_a_command_whose_drive_outlasts_its_timeout_is_carried_through(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    layers = tmp_path / "robot.layers"
    layers.write_text("parameter Slow: base max_speed = 0.3\n", encoding="utf-8")
    plain = processes.start(
        "plain nodes", [str(HERE / "plain_nodes_process.py"), "--slow-set", str(SLOW_SET)]
    )
    processes.participant("d1")
    manager = processes.manager("--liveness-timeout", LIVENESS, "--layers", str(layers))
    plain.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    wait_for_manager(client, manager)
    wait_registry(client, lambda r: any(p.node == "/d1" for p in r.participants) and r.epoch)
    answers: dict[str, Any] = {}

    def first() -> None:
        answers["slow"] = client.request(["Slow"], synchronous=True, timeout=1.0)
        answers["slow_at"] = time.monotonic()

    def behind() -> None:
        # Its own node and executor: this thread spins it while `first` spins the other.
        node = Node("drive_deadline_client")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            other = LayerClient(node, "pytest", executor=executor)
            other.wait_for_manager(10.0)
            time.sleep(0.3)  # the drive of Slow is under way
            answers["night"] = other.request(["Night"], synchronous=True, timeout=0.5)
            answers["night_at"] = time.monotonic()
        finally:
            executor.remove_node(node)
            node.destroy_node()

    threads = [threading.Thread(target=f, daemon=True) for f in (first, behind)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(15)
    night = answers["night"]
    assert not night.success, night.message
    assert "behind the parameters and lifecycle states of the command before it" in night.message
    assert "nothing changed" in night.message
    assert answers["night_at"] < answers["slow_at"], "refused at its deadline, not after"
    slow = answers["slow"]
    assert "nothing changed" not in slow.message, slow.message
    assert "Slow" in client.query().active_layers
    # The value stays: not set, then put back by a reconcile.
    time.sleep(0.5)
    assert max_speed(client) == 0.3
    assert "Slow" in client.query().active_layers
