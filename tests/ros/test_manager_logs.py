"""The manager's log says what happened (issue 24, item 8): a rule that turns a layer off
says so, and an epoch published but not confirmed is not logged as a refusal."""

from __future__ import annotations

import time
from pathlib import Path

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import LIVENESS, wait_registry
from tests.ros.test_rules import Sensors


def wait_log(manager: Child, text: str, timeout: float = 5.0) -> str:
    deadline = time.monotonic() + timeout
    while text not in manager.output():
        assert time.monotonic() < deadline, f"not logged: {text!r}\n{manager.output()}"
        time.sleep(0.05)
    return manager.output()


def test_the_manager_log_says_what_happened(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    rules = tmp_path / "robot.layers"
    rules.write_text("rule Battery: Night while battery.percentage < 20\n", encoding="utf-8")
    processes.participant("l1")
    manager = processes.manager("--liveness-timeout", LIVENESS, "--rules", str(rules))
    client.wait_for_manager(15.0)
    wait_registry(client, lambda r: any(p.node == "/l1" for p in r.participants) and r.epoch)
    sensors = Sensors(client)
    try:
        sensors.keep_publishing(
            lambda: "Night" in client.query().active_layers, percentage=10.0, what="Night on"
        )
        sensors.keep_publishing(
            lambda: "Night" not in client.query().active_layers, percentage=50.0, what="off"
        )
    finally:
        sensors.node.destroy_node()
    log = wait_log(manager, "rule Battery switched Night off: 1 node(s) applied it")
    assert "switched to without" not in log
    # Published, applied by /l1, not confirmed for a node that does not exist: no refusal.
    result = client.request(["Slow"], synchronous=True, timeout=0.5, expect_nodes=["/ghost"])
    assert not result.success and "not confirmed" in result.message
    log = wait_log(manager, f"answered: epoch {result.epoch} not confirmed")
    assert f"refused: epoch {result.epoch}" not in log
