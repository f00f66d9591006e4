"""Atomic activation with participant processes: all switch to the committed epoch, or a
veto aborts it and no node changes (issue 10)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import RunningSystem, settle, start_system

NODES = ("/t1", "/t2", "/t3")


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        yield start_system(group, client, ["t1", "t2", "t3"])
    finally:
        group.kill_all()


def test_every_node_votes_then_all_apply_the_committed_epoch(
    system: RunningSystem, client: LayerClient
) -> None:
    before = settle(client, "Indoor")
    result = client.request(["Night"], atomic=True, timeout=5)
    assert result.success, result.message
    assert result.epoch == before.epoch + 1 and result.acknowledged == NODES
    assert result.active == ("Indoor", "Night")
    for child in system.participants.values():
        assert child.wait_applied(result.epoch)["mode"] == "quiet+wipe+base"


def test_a_veto_aborts_and_no_node_changes(system: RunningSystem, client: LayerClient) -> None:
    before = settle(client, "Indoor")
    t2 = system.participants["t2"]
    t2.send("critical 3")
    t2.wait_for(lambda events: any(e["event"] == "critical-open" for e in events), 5)
    started = time.monotonic()
    result = client.request(["Outdoor"], atomic=True, timeout=5)
    assert time.monotonic() - started < 2.0, "a veto is answered at once, not at the timeout"
    assert not result.success and result.not_acknowledged == ("/t2",)
    assert "aborted, nothing changed: /t2 vetoed: in a critical section" in result.message
    assert (result.epoch, result.active) == (before.epoch, ("Indoor",))
    time.sleep(0.5)
    assert client.query().epoch == before.epoch
    for name, child in system.participants.items():
        # Epochs, not line counts: a node's last "applied" line may still be on its way.
        switched = [e for e in child.applied() if e["epoch"] > before.epoch]
        assert not switched, f"{name} switched: {switched}"
    # Once the section is over, the same request commits.
    t2.wait_for(lambda events: any(e["event"] == "critical-closed" for e in events), 5)
    time.sleep(0.3)  # the line is printed just before the section's last statement ends
    again = client.request(["Outdoor"], atomic=True, timeout=5)
    assert again.success and again.acknowledged == NODES, again.message
    assert again.epoch == before.epoch + 2, "the aborted epoch is skipped, never reused"
