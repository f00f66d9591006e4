"""C++ context nodes (the rcl participant, cpp/ros) with the Python Layer manager and Python
context nodes: the same activations, acknowledgements, refusals and faults as in Python.

The C++ test participant (cpp/ros/tests/participant_process.cpp) has the same layers,
relations, layered method and JSON output as tests/ros/participant_process.py.
"""

from __future__ import annotations

import signal
import threading
import time

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import LIVENESS, start_system, wait_registry


def ready(child: Child) -> dict[str, object]:
    return child.wait_for(
        lambda events: next((e for e in events if e["event"] == "ready"), None), 15, "ready"
    )


def test_one_synchronous_activation_switches_cpp_and_python_nodes_together(
    client: LayerClient, processes: ProcessGroup
) -> None:
    cpp = processes.cpp_participant("cxx")
    assert ready(cpp)["mode"] == "base"
    system = start_system(processes, client, ["py"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    result = client.request(["Indoor"], synchronous=True, timeout=5, reason="inside")
    assert result.success, result.message
    assert result.acknowledged == ("/cxx", "/py") and result.not_acknowledged == ()
    night = client.request(["Night"], synchronous=True, timeout=5)
    assert night.success, night.message
    assert night.acknowledged == ("/cxx", "/py")
    for child in (cpp, system.participants["py"]):
        applied = child.wait_applied(night.epoch, timeout=2)
        assert applied["epoch"] == night.epoch
        assert applied["active"] == ["Indoor", "Night"]
        assert applied["mode"] == "quiet+wipe+base", f"{child.name} follows the manager"
    registry = client.query()
    cxx = next(p for p in registry.participants if p.node == "/cxx")
    assert cxx.applied_epoch == night.epoch
    assert set(cxx.layers) == {"Indoor", "Outdoor", "Night", "Slow", "Fast", "Gps"}
    gps = next(layer for layer in registry.layers if layer.name == "Gps")
    assert list(gps.required) == ["Outdoor"], "relations announced by the C++ node"
    # The manager validates against the C++ node's relations too.
    rejected = client.request(["Slow", "Fast"], synchronous=True, timeout=5)
    assert not rejected.success and "Slow excludes Fast" in rejected.message


def test_a_cpp_node_that_cannot_apply_a_state_fails_the_activation_naming_it(
    client: LayerClient, processes: ProcessGroup
) -> None:
    stubborn = processes.cpp_participant("stubborn_cxx", "--refuse", "Night")
    ready(stubborn)
    start_system(processes, client, ["willing"])
    # Both on the manager's current state: a node whose first state is the refused one
    # has applied nothing to stay on.
    wait_registry(
        client,
        lambda r: (
            len(r.participants) == 2 and all(p.applied_epoch == r.epoch for p in r.participants)
        ),
        what="both participants on the current state",
    )
    stubborn.wait_applied(1)
    started = time.monotonic()
    refused = client.request(["Night"], synchronous=True, timeout=10)
    assert time.monotonic() - started < 2.0, "a failure is reported, not waited out"
    assert not refused.success
    assert refused.acknowledged == ("/willing",)
    assert refused.not_acknowledged == ("/stubborn_cxx",)
    assert "/stubborn_cxx (failed to apply: epoch" in refused.message, refused.message
    assert "Night requires Sunlight" in refused.message, refused.message
    # It stays on what it had, and follows the next state it can apply.
    assert stubborn.applied()[-1]["active"] == []
    following = client.request(["Outdoor"], ["Night"], synchronous=True, timeout=5)
    assert following.success, following.message
    assert stubborn.wait_applied(following.epoch)["mode"] == "vacuum+base"


def test_a_cpp_critical_section_delays_the_acknowledgement(
    client: LayerClient, processes: ProcessGroup
) -> None:
    cpp = processes.cpp_participant("careful_cxx")
    ready(cpp)
    start_system(processes, client, ["quick"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    hold = 1.0
    cpp.send(f"critical {hold}")
    opened = cpp.wait_for(
        lambda events: next((e for e in events if e["event"] == "critical-open"), None), 5
    )
    result = client.request(["Outdoor"], synchronous=True, timeout=10)
    assert result.success, result.message
    assert result.acknowledged == ("/careful_cxx", "/quick")
    closed = cpp.wait_for(
        lambda events: next((e for e in events if e["event"] == "critical-closed"), None), 5
    )
    applied = cpp.wait_applied(result.epoch)
    assert applied["t"] >= closed["t"], "the switch waited for the critical section"
    assert closed["t"] - opened["t"] >= hold * 0.9
    assert result.elapsed >= 0.5, (
        f"answered after {result.elapsed:.3f} s, before the section closed"
    )


def test_sigkill_of_a_cpp_node_is_detected_within_the_liveness_bound(
    client: LayerClient, processes: ProcessGroup
) -> None:
    victim = processes.cpp_participant("victim_cxx")
    ready(victim)
    start_system(processes, client, ["survivor"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    # Held in a critical section, so it is surely in the middle of the activation.
    victim.send("critical 30")
    victim.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5)
    killer_delay = 0.3
    started = time.monotonic()
    threading.Timer(killer_delay, victim.signal, args=(signal.SIGKILL,)).start()
    result = client.request(["Night"], synchronous=True, timeout=20)
    elapsed = time.monotonic() - started
    assert not result.success
    assert result.not_acknowledged == ("/victim_cxx",), result.message
    assert "/victim_cxx (dropped, silent for" in result.message
    assert result.acknowledged == ("/survivor",)
    # Liveness timeout (the tests' manager: 1 s) + heartbeat and tick granularity.
    assert elapsed < killer_delay + float(LIVENESS) + 1.0, f"took {elapsed:.2f} s to notice"
    assert "/victim_cxx" in list(client.query().dropped)


def test_a_late_cpp_node_gets_the_current_state_and_a_clean_exit_leaves_at_once(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["early_py"])
    current = client.request(["Outdoor", "Night"], synchronous=True, timeout=5)
    assert current.success, current.message
    late = processes.cpp_participant("late_cxx", "--also", "late_guest")
    applied = late.wait_applied(current.epoch, timeout=10)
    assert applied["active"] == ["Outdoor", "Night"]
    assert applied["mode"] == "quiet+vacuum+base"
    registry = wait_registry(
        client,
        lambda r: any(p.node == "/late_cxx" for p in r.participants),
        what="the late C++ node registered",
    )
    cxx = next(p for p in registry.participants if p.node == "/late_cxx")
    assert list(cxx.hosted_nodes) == ["/late_guest"], "one participant for the process"
    result = client.request(["Indoor"], synchronous=True, timeout=5)
    assert result.success, result.message
    assert result.acknowledged == ("/early_py", "/late_cxx", "/late_guest")
    late.send("quit")
    assert late.wait_exit() == 0
    # Dropped because it said it leaves, not because it fell silent.
    deadline = time.monotonic() + 10
    while not any("/late_cxx dropped: left" in line for line in system.manager.lines):
        assert time.monotonic() < deadline, system.manager.output()
        time.sleep(0.05)
    assert [p.node for p in client.query().participants] == ["/early_py"]


def test_a_cpp_node_votes_in_an_atomic_activation(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """Issue 10's atomic activation with a C++ and a Python participant: the C++ one vetoes
    while in a critical section (nothing changes anywhere), then both commit one epoch."""
    cpp = processes.cpp_participant("voter_cxx")
    ready(cpp)
    start_system(processes, client, ["voter_py"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    before = client.query()
    cpp.send("critical 1.5")
    cpp.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5)
    vetoed = client.request(["Outdoor"], atomic=True, timeout=5)
    assert not vetoed.success and vetoed.not_acknowledged == ("/voter_cxx",), vetoed.message
    assert "/voter_cxx vetoed: in a critical section" in vetoed.message
    assert client.query().epoch == before.epoch, "nothing changed"
    cpp.wait_for(lambda events: any(e["event"] == "critical-closed" for e in events), 5)
    time.sleep(0.3)  # the line is printed just before the section's last statement ends
    committed = client.request(["Outdoor"], atomic=True, timeout=5)
    assert committed.success, committed.message
    assert committed.acknowledged == ("/voter_cxx", "/voter_py")
    assert cpp.wait_applied(committed.epoch)["mode"] == "vacuum+base"


def test_a_cpp_node_stopped_during_its_veto_waits_for_it_before_exiting(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """A veto is user code on a worker thread: a node stopped while it thinks lets it answer
    before the process exits (not run on during static destruction)."""
    cpp = processes.cpp_participant("stopping_cxx", "--veto-sleep", "1.5")
    ready(cpp)
    start_system(processes, client, ["stopping_py"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    asking = threading.Thread(
        target=lambda: client.request(["Night"], atomic=True, timeout=5), daemon=True
    )
    asking.start()
    cpp.wait_for(lambda events: any(e["event"] == "veto-called" for e in events), 10, "a veto")
    cpp.send("quit")
    assert cpp.wait_exit(10) == 0, cpp.output()
    assert any(e["event"] == "veto-answered" for e in cpp.events), cpp.output()
    asking.join(10)


def test_a_cpp_nodes_slow_veto_is_asked_once_and_the_node_stays_live(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """Issue 24: a veto thinking longer than the liveness bound (1 s here) runs off the
    participant's thread, once per proposal; the node's heartbeats go on meanwhile."""
    cpp = processes.cpp_participant("slow_cxx", "--veto-sleep", "1.5")
    ready(cpp)
    start_system(processes, client, ["quick_py"])
    wait_registry(client, lambda r: len(r.participants) == 2, what="both participants")
    committed = client.request(["Night"], atomic=True, timeout=5)
    assert committed.success, committed.message
    assert committed.acknowledged == ("/quick_py", "/slow_cxx")
    calls = [e for e in cpp.events if e["event"] == "veto-called"]
    assert [e["epoch"] for e in calls] == [committed.epoch], calls
