"""A manager killed and restarted with its state file keeps its promises (issue 24): an
epoch it proposed is never reused, and the nodes it knew are awaited, not forgotten."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import rclpy

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import settle, start_system, wait_registry


def restart_manager(processes: ProcessGroup, state_file: Path, liveness: str = "1.0") -> None:
    manager = next(c for c in processes.children if c.name == "manager")
    manager.signal(signal.SIGKILL)
    manager.wait_exit()
    processes.manager("--liveness-timeout", liveness, "--state-file", str(state_file), name="m2")


def test_an_epoch_proposed_before_a_crash_is_never_reused(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    state_file = tmp_path / "state.json"
    # The vote stays open while /v1's veto thinks: the manager dies during it.
    v1 = processes.participant("v1", "--veto-sleep", "1.0")
    v2 = processes.participant("v2")
    processes.manager("--liveness-timeout", "1.0", "--state-file", str(state_file))
    client.wait_for_manager(15.0)
    wait_registry(client, lambda r: len(r.participants) == 2 and not r.recovering)
    before = settle(client, "Indoor")
    proposed = before.epoch + 1
    future = client.request_async(["Night"], atomic=True, timeout=5)
    v1.wait_for(lambda events: any(e["event"] == "veto-called" for e in events), 5, "the vote")
    restart_manager(processes, state_file)
    client._activate.remove_pending_request(future)
    recovered = wait_registry(
        client, lambda r: r.epoch > before.epoch and not r.recovering, what="recovery"
    )
    # Epoch `proposed` named [Indoor, Night] in the vote: it never names another set.
    assert recovered.epoch == proposed + 1, recovered.epoch
    assert list(recovered.active_layers) == ["Indoor"]
    for child in (v1, v2):
        child.wait_applied(recovered.epoch)
        assert proposed not in [e["epoch"] for e in child.applied()], child.name


def test_a_synchronous_answer_after_a_restart_waits_for_the_nodes_known_before(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    state_file = tmp_path / "state.json"
    system = start_system(processes, client, ["k1", "k2"], "--state-file", str(state_file))
    before = settle(client, "Indoor")
    k2 = system.participants["k2"]
    k2.signal(signal.SIGSTOP)  # it cannot report to the new manager for a while
    try:
        # A node known before the restart gets the liveness bound (5 s) to report again.
        restart_manager(processes, state_file, liveness="5.0")
        # /k1 reported to the new manager (its layers are known again), /k2 cannot.
        wait_registry(
            client,
            lambda r: (
                r.epoch > before.epoch
                and not r.recovering
                and any(p.node == "/k1" and "Night" in p.layers for p in r.participants)
            ),
        )
        future = client.request_async(["Night"], synchronous=True, timeout=4)
        time.sleep(0.3)
    finally:
        k2.signal(signal.SIGCONT)
    rclpy.spin_until_future_complete(client.node, future, timeout_sec=8)
    result = client.result_of(future)
    # Before: success at once, "applied by 1 node(s)", while /k2 was live before the crash.
    logs = "\n".join(c.output() for c in processes.children if c.name == "m2")
    assert result.success, f"{result.message}\n{logs}"
    assert result.acknowledged == ("/k1", "/k2"), f"{result.message}\n{logs}"
