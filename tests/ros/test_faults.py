"""Faults: a participant killed mid-activation, a manager killed and restarted."""

from __future__ import annotations

import itertools
import json
import signal
import time

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import start_system, wait_registry
from tests.ros.test_cli import contextros


def test_participant_started_before_the_manager_joins_when_it_appears(
    client: LayerClient, processes: ProcessGroup
) -> None:
    early = processes.participant("early")
    ready = early.wait_for(
        lambda events: next((e for e in events if e["event"] == "ready"), None), 15, "ready"
    )
    assert ready["mode"] == "base", "without a manager the node runs its base behaviour"
    time.sleep(0.3)
    assert early.applied() == []
    processes.manager("--liveness-timeout", "1.0")
    early.wait_applied(1, timeout=10)
    wait_registry(client, lambda r: [p.node for p in r.participants] == ["/early"], what="joined")
    result = client.request(["Outdoor"], synchronous=True, timeout=5)
    assert result.success and result.acknowledged == ("/early",), result.message
    assert early.wait_applied(result.epoch)["mode"] == "vacuum+base"


def test_participant_killed_during_a_synchronous_activation(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["k1", "k2", "k3"])
    victim = system.participants["k3"]
    # Hold k3 in a critical section so that it is surely in the middle of the activation.
    victim.send("critical 30")
    victim.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5)
    killer_delay = 0.3
    started = time.monotonic()
    # The in-process client spins only its own node, so kill from a timer thread.
    import threading

    threading.Timer(killer_delay, victim.signal, args=(signal.SIGKILL,)).start()
    result = client.request(["Night"], synchronous=True, timeout=20)
    elapsed = time.monotonic() - started
    assert not result.success
    assert result.not_acknowledged == ("/k3",), result.message
    assert "/k3 (dropped, silent for" in result.message
    assert result.acknowledged == ("/k1", "/k2")
    # Liveness timeout 1 s (tests' manager) + heartbeat and tick granularity.
    assert elapsed < killer_delay + 2.0, f"took {elapsed:.2f} s to notice"
    registry = client.query()
    assert "/k3" in list(registry.dropped)
    following = client.request(["Indoor"], synchronous=True, timeout=5)
    assert following.success, following.message
    assert following.acknowledged == ("/k1", "/k2")


def test_restarted_manager_keeps_epochs_monotonic_and_the_active_set(
    client: LayerClient, processes: ProcessGroup, tmp_path: object
) -> None:
    from pathlib import Path

    state_file = Path(str(tmp_path)) / "state.json"
    system = start_system(processes, client, ["r1", "r2", "r3"], "--state-file", str(state_file))
    client.request(["Outdoor", "Night"], synchronous=True, timeout=5)
    before = client.request(["Gps"], synchronous=True, timeout=5)
    assert before.success, before.message

    # 1. Killed and restarted with its state file.
    system.manager.signal(signal.SIGKILL)
    system.manager.wait_exit()
    processes.manager("--liveness-timeout", "1.0", "--state-file", str(state_file), name="m2")
    second = wait_registry(client, lambda r: r.epoch > before.epoch, what="recovered state")
    assert second.epoch == before.epoch + 1
    assert list(second.active_layers) == ["Outdoor", "Night", "Gps"]

    # 2. Killed and restarted without memory: the participants remember (once they have
    # applied the state: without a state file, an epoch that reached nobody is forgotten).
    wait_registry(
        client,
        lambda r: [p.applied_epoch for p in r.participants] == [second.epoch] * 3,
        what="participants on the recovered state",
    )
    second_manager = processes.children[-1]
    second_manager.signal(signal.SIGKILL)
    second_manager.wait_exit()
    third_manager = processes.manager("--liveness-timeout", "1.0", name="m3")
    try:
        third = wait_registry(client, lambda r: r.epoch > second.epoch, what="recovered state")
    except AssertionError as error:
        logs = "\n".join(f"--- {c.name}:\n{c.output()}" for c in processes.children[3:])
        raise AssertionError(f"{error}\n{logs}") from None
    del third_manager
    # Without memory it numbers its first state 1000 above what it heard (docs/protocol.md).
    assert third.epoch == second.epoch + 1000
    assert list(third.active_layers) == ["Outdoor", "Night", "Gps"]
    assert "recovered from /r" in third.reason

    wait_registry(client, lambda r: len(r.participants) == 3, what="all participants back")
    after = client.request(["Indoor"], ["Gps"], synchronous=True, timeout=5)
    assert after.success and after.epoch == third.epoch + 1
    assert after.acknowledged == ("/r1", "/r2", "/r3")
    for child in system.participants.values():
        child.wait_applied(after.epoch)
        epochs = [e["epoch"] for e in child.applied()]
        assert all(a < b for a, b in itertools.pairwise(epochs)), f"{child.name}: {epochs}"
        assert epochs[-1] == after.epoch


def test_a_node_that_cannot_apply_a_state_is_named_at_once(
    client: LayerClient, processes: ProcessGroup
) -> None:
    processes.participant("stubborn", "--stubborn", "Night")
    start_system(processes, client, ["willing"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    assert client.request(["Night"], synchronous=True, timeout=5).success
    started = time.monotonic()
    refused = client.request([], ["Night"], synchronous=True, timeout=10)
    assert time.monotonic() - started < 2.0, "a failure is reported, not waited out"
    assert not refused.success
    assert refused.acknowledged == ("/willing",)
    assert refused.not_acknowledged == ("/stubborn",)
    assert "/stubborn (failed to apply: epoch" in refused.message
    assert "Night cannot be left now" in refused.message
    # `status` says it refused, and why, not only that it lags (issue 24, item 7).
    shown = contextros("status")
    assert "REFUSED: /stubborn could not apply epoch" in shown.stdout, shown.stdout
    assert "Night cannot be left now" in shown.stdout
    data = json.loads(contextros("status", "--json").stdout)
    stubborn = next(p for p in data["participants"] if p["node"] == "/stubborn")
    assert stubborn["failed_epoch"] == refused.epoch
    assert "Night cannot be left now" in stubborn["error"]


def test_a_manager_that_waited_for_a_core_drops_no_node_whose_reports_it_holds(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """On a loaded machine the manager may not run for longer than the liveness bound (1 s
    here) while its nodes keep reporting: the reports waiting for it count first."""
    system = start_system(processes, client, ["w1", "w2"])
    before = list(client.query().dropped)
    system.manager.signal(signal.SIGSTOP)
    try:
        time.sleep(2.5)
    finally:
        system.manager.signal(signal.SIGCONT)
    time.sleep(1.0)
    registry = client.query()
    assert list(registry.dropped) == before, "dropped although their reports were waiting"
    assert {p.node for p in registry.participants} == {"/w1", "/w2"}
    output = system.manager.output()
    assert "dropped" not in output.split("recovering from")[-1], output
