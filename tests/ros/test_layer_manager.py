"""The Layer manager with three participant processes: the normal life of a system.

One manager and participants /p1, /p2, /p3 serve the whole module; each test leaves them
running and consistent for the next.
"""

from __future__ import annotations

import itertools
import signal
import time
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.node import Node

from contextros.ros import LayerClient
from tests.ros.processes import CLIENT_SCRIPT, ProcessGroup
from tests.ros.system import RunningSystem, settle, start_system, wait_registry

NODES = ("/p1", "/p2", "/p3")


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        yield start_system(group, client, ["p1", "p2", "p3"])
    finally:
        group.kill_all()


def test_synchronous_activation_is_acknowledged_by_every_participant(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client, "Indoor")
    result = client.request(["Night"], synchronous=True, timeout=5, reason="dusk")
    assert result.success, result.message
    assert result.acknowledged == NODES and result.not_acknowledged == ()
    assert result.active == ("Indoor", "Night")
    for child in system.participants.values():
        # The node printed this line right after acknowledging: it may lag the answer a little.
        applied = child.wait_applied(result.epoch, timeout=2)
        assert applied["epoch"] == result.epoch
        assert applied["mode"] == "quiet+wipe+base", "the layered method follows the manager"


def test_unknown_layer_is_rejected_by_name_and_nothing_changes(
    system: RunningSystem, client: LayerClient
) -> None:
    before = client.query()
    result = client.request(["Night", "Underwater"], synchronous=True, timeout=5)
    assert not result.success
    assert "'Underwater'" in result.message and "nothing changed" in result.message
    after = client.query()
    assert (after.epoch, list(after.active_layers)) == (before.epoch, list(before.active_layers))
    time.sleep(0.2)
    for child in system.participants.values():
        assert child.applied()[-1]["epoch"] == before.epoch


@pytest.mark.parametrize(
    ("on", "off", "culprit"),
    [
        (["Gps"], [], "Gps requires Outdoor"),
        (["Slow", "Fast"], [], "Slow excludes Fast"),
        (["Indoor", "Outdoor"], [], "exclusive group 'location'"),
    ],
)
def test_relation_violation_is_rejected_and_nothing_changes(
    system: RunningSystem, client: LayerClient, on: list[str], off: list[str], culprit: str
) -> None:
    before = settle(client, "Indoor")
    result = client.request(on, off, synchronous=True, timeout=5)
    assert not result.success and culprit in result.message, result.message
    assert client.query().epoch == before.epoch


def test_switch_is_one_atomic_state_everywhere(system: RunningSystem, client: LayerClient) -> None:
    settle(client, "Night", "Indoor")
    result = client.request(["Outdoor", "Gps"], ["Indoor"], synchronous=True, timeout=5)
    assert result.success, result.message
    for child in system.participants.values():
        applied = child.wait_applied(result.epoch, timeout=2)
        assert applied["active"] == ["Night", "Outdoor", "Gps"]
        assert applied["mode"] == "vacuum+quiet+base"
    client.request(["Indoor"], ["Gps"], synchronous=True, timeout=5)


def test_late_joiner_gets_the_current_state_at_once(
    system: RunningSystem, client: LayerClient, processes: ProcessGroup
) -> None:
    current = client.query()
    late = processes.participant("p4")
    # Starting a process (Python, rclpy) takes seconds when the machine is loaded; the
    # state then comes at once (transient local), without a new one being published.
    late.wait_for(lambda events: any(e["event"] == "ready" for e in events), 30, "ready")
    applied = late.wait_applied(current.epoch, timeout=5)
    assert applied["active"] == list(current.active_layers)
    registry = wait_registry(client, lambda r: "/p4" in {p.node for p in r.participants})
    assert registry.epoch == current.epoch, "joining does not change the state"
    late.signal(signal.SIGTERM)
    assert late.wait_exit() == 0, "SIGTERM ends a context node cleanly"
    left = time.monotonic()
    wait_registry(client, lambda r: "/p4" not in {p.node for p in r.participants}, what="/p4 gone")
    # It said it leaves: no need to wait for the liveness timeout (1 s here).
    assert time.monotonic() - left < 0.9


def test_critical_section_delays_the_acknowledgement(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client, "Night")
    p1 = system.participants["p1"]
    p1.send("critical 1.5")
    p1.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5, "critical")
    unchanged = client.request(["Night"], synchronous=True, timeout=0.1)
    assert unchanged.success, "no change: every node already applied the current epoch"
    started = time.monotonic()
    short = client.request([], ["Night"], synchronous=True, timeout=0.4)
    assert not short.success
    assert short.not_acknowledged == ("/p1",)
    assert "/p1 (in a critical section" in short.message
    patient = client.request(["Night"], synchronous=True, timeout=5)
    waited = time.monotonic() - started
    assert patient.success, patient.message
    assert waited > 1.0, "the acknowledgement waited for the critical section"
    p1.wait_applied(patient.epoch, timeout=2)
    closed = next(e for e in p1.events if e["event"] == "critical-closed")
    applied = [e for e in p1.applied() if e["epoch"] >= short.epoch]
    assert applied and all(e["t"] >= closed["t"] for e in applied)


def test_rapid_activations_from_two_clients_converge_without_regression(
    system: RunningSystem, client: LayerClient, processes: ProcessGroup
) -> None:
    watch = processes.start("watch", ["-m", "contextros", "watch", "--json", "--duration", "60"])
    watch.wait_for(lambda events: any(e["event"] == "current" for e in events), 10, "watching")
    script = str(CLIENT_SCRIPT)
    location = processes.start(
        "client-location",
        [script, "--name", "c_location", "--count", "100", "--layers", "Indoor,Outdoor"],
    )
    night = processes.start(
        "client-night", [script, "--name", "c_night", "--count", "100", "--toggle", "Night"]
    )
    for child in (location, night):
        child.wait_for(lambda events: any(e["event"] == "done" for e in events), 60, "done")
        results = [e for e in child.events if e["event"] == "result"]
        assert len(results) == 100 and all(r["success"] for r in results)
        epochs = [r["epoch"] for r in results]
        assert epochs == sorted(epochs), f"{child.name} saw the epoch go down"
    final = client.query()
    assert final.epoch >= 100
    for child in system.participants.values():
        child.wait_applied(final.epoch, timeout=5)
        epochs = [e["epoch"] for e in child.applied()]
        assert all(a < b for a, b in itertools.pairwise(epochs)), f"{child.name} regressed"
        assert child.applied()[-1]["active"] == list(final.active_layers)
    watch.wait_for(lambda events: any(e.get("epoch") == final.epoch for e in events), 5, "final")
    seen = [e["epoch"] for e in watch.events if e["event"] in ("current", "state")]
    assert all(a < b for a, b in itertools.pairwise(seen)), "the watcher saw the epoch go down"
    wait_registry(
        client,
        lambda r: [p.applied_epoch for p in r.participants] == [final.epoch] * 3,
        what="every participant's acknowledgement of the final epoch",
    )


def test_asynchronous_request_from_a_callback_style_future(
    system: RunningSystem, client: LayerClient
) -> None:
    import rclpy

    before = settle(client, "Indoor")
    future = client.request_async(["Night"], reason="from a callback")
    rclpy.spin_until_future_complete(client.node, future, timeout_sec=10)
    result = client.result_of(future)
    assert result.success and result.epoch == before.epoch + 1
    assert result.acknowledged == (), "asynchronous: answered once published"
    for child in system.participants.values():
        assert child.wait_applied(result.epoch)["active"] == ["Indoor", "Night"]


def test_concurrent_synchronous_answers_describe_their_own_epoch(
    system: RunningSystem, client: LayerClient, processes: ProcessGroup
) -> None:
    """Issue 10: with 3 concurrent clients, 173 of 564 answers carried a later epoch's
    layers. Each answer's layers must be those its epoch had in every node."""
    settle(client, "Indoor")
    script = str(CLIENT_SCRIPT)
    clients = [
        processes.start(
            "client-location",
            [
                script,
                "--name",
                "s_location",
                "--count",
                "30",
                "--layers",
                "Indoor,Outdoor",
                "--sync",
            ],
        ),
        processes.start(
            "client-night",
            [script, "--name", "s_night", "--count", "30", "--toggle", "Night", "--sync"],
        ),
        processes.start(
            "client-slow",
            [script, "--name", "s_slow", "--count", "30", "--toggle", "Slow", "--sync"],
        ),
    ]
    answers = []
    for child in clients:
        child.wait_for(lambda events: any(e["event"] == "done" for e in events), 90, "done")
        answers += [e for e in child.events if e["event"] == "result"]
    assert all(a["success"] for a in answers), [a["message"] for a in answers if not a["success"]]
    final = client.query().epoch
    applied: dict[int, list[str]] = {}
    for child in system.participants.values():
        child.wait_applied(final, timeout=5)
        for event in child.applied():
            known = applied.setdefault(event["epoch"], event["active"])
            assert known == event["active"], f"two configurations for epoch {event['epoch']}"
    checked = [a for a in answers if a["epoch"] in applied]
    assert len(checked) >= len(answers) // 2, "enough answers can be checked"
    wrong = [a for a in checked if a["active"] != applied[a["epoch"]]]
    assert wrong == [], f"{len(wrong)} of {len(checked)} answers show another epoch's layers"


def test_a_client_slow_to_take_its_answers_still_gets_each_one(
    system: RunningSystem, client: LayerClient, processes: ProcessGroup
) -> None:
    """Issue 16: a storm from 3 clients lost 3 of 1800 answers. Fast DDS hands every reply
    of a service to every client's reply reader and filters them by requester only when
    a client takes one: a client that did not take for a while found its own replies
    pushed out of that reader's history by other clients' replies (depth 10)."""
    settle(client, "Indoor")
    node = Node("slow_client")
    try:
        slow = LayerClient(node, requester="slow")
        slow.wait_for_manager(10.0)
        # Three answers wait, untaken, while another client gets 40 of its own.
        on_off = [((), ["Night"]), (["Night"], ()), ((), ["Night"])]
        futures = [slow.request_async(on, off) for on, off in on_off]
        busy = processes.start(
            "client-busy",
            [str(CLIENT_SCRIPT), "--name", "busy", "--count", "40", "--toggle", "Slow"],
        )
        busy.wait_for(lambda events: any(e["event"] == "done" for e in events), 60, "done")
        deadline = time.monotonic() + 5.0
        while not all(future.done() for future in futures) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        answered = [slow.result_of(future).success for future in futures if future.done()]
        assert answered == [True, True, True]
    finally:
        node.destroy_node()
