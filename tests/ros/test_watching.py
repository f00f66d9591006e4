"""`contextros watch` against a manager and participant processes: it reports what the
manager reports (refusals, the nodes it counts), never an epoch applied by a node that
refused it.

Issue: watch printed `epoch 1034 applied by all 2 live node(s)` for an epoch both nodes
refused, once they applied 1035; and `applied by all 2` where the manager said
`acknowledged by 3`, missing a node that hosts another and one with a slow heartbeat.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from typing import Any

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import RunningSystem, start_system, wait_registry

# The manager's liveness bound here, longer than the watch's default (3 s): the slow node
# beats every 8 s, so it is silent for more than 3 s after each report.
LIVENESS = "20"


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[tuple[RunningSystem, ProcessGroup]]:
    group = ProcessGroup()
    try:
        yield start_system(group, client, ["wplain"], "--liveness-timeout", LIVENESS), group
    finally:
        group.kill_all()


def start_watch(group: ProcessGroup, nodes: set[str]) -> Child:
    watch = group.start("watch", ["-m", "contextros", "watch", "--json"])
    watch.wait_for(
        lambda events: (
            {e.get("node") for e in events if e["event"] == "node"} >= nodes
            and any(e["event"] == "current" for e in events)
        ),
        10,
        f"the current state and {sorted(nodes)}",
    )
    return watch


def settled(watch: Child, epoch: int) -> dict[str, Any]:
    return watch.wait_for(
        lambda events: next(
            (
                e
                for e in events
                if e["event"] in ("applied", "not-applied") and e.get("epoch") == epoch
            ),
            None,
        ),
        10,
        f"epoch {epoch} settled",
    )


def stop(*children: Child) -> None:
    """Stopped as by Ctrl-C: a node leaves (the manager, whose bound is long, drops it)."""
    for child in children:
        child.signal(signal.SIGINT)
    for child in children:
        child.wait_exit(10)


def test_a_refused_epoch_is_reported_never_applied_by_all(
    system: tuple[RunningSystem, ProcessGroup], client: LayerClient
) -> None:
    """/wstub's on_deactivate hook of Night raises: leaving Night is refused by it, and
    the next epoch, keeping Night, applied by all. The refused one stays refused."""
    _, group = system
    stubborn = group.participant("wstub2", "--stubborn", "Night")
    wait_registry(client, lambda r: "/wstub2" in {p.node for p in r.participants})
    if "Night" not in client.query().active_layers:
        assert client.request(["Night"], synchronous=True, timeout=5).success
    watch = start_watch(group, {"/wstub2", "/wplain"})
    refused = client.request([], ["Night"], synchronous=True, timeout=5)
    assert not refused.success and "/wstub2" in refused.message, refused.message
    again = client.request(["Night"], synchronous=True, timeout=5)
    assert again.success, again.message
    later = settled(watch, again.epoch)
    outcome = settled(watch, refused.epoch)
    stop(watch, stubborn)
    refusals = [e for e in watch.events if e["event"] == "refused"]
    assert [(e["epoch"], e["node"]) for e in refusals] == [(refused.epoch, "/wstub2")]
    assert "Night cannot be left now" in refusals[0]["error"]
    assert f"epoch {refused.epoch}" in refusals[0]["error"]  # as `status` shows it
    assert outcome["event"] == "not-applied", outcome
    assert outcome["refused_by"] == ["/wstub2"]
    assert "/wplain" in outcome["applied_by"]
    assert later["event"] == "applied"
    assert later["nodes"] == len(again.acknowledged)


def test_watch_counts_the_nodes_the_manager_counts(
    system: tuple[RunningSystem, ProcessGroup], client: LayerClient
) -> None:
    """A process hosting a second node (the manager counts both) and a node silent for
    longer than 3 s between its reports (the manager's bound here is 20 s)."""
    _, group = system
    hosting = group.participant("whost", "--also", "whosted")
    slow = group.participant("wslow", "--heartbeat", "8", "--manager-timeout", LIVENESS)
    wanted = {"/whost", "/wslow"}
    wait_registry(client, lambda r: {p.node for p in r.participants} >= wanted)
    watch = start_watch(group, {"/whost", "/wslow", "/wplain"})
    location = "Outdoor" if "Indoor" in client.query().active_layers else "Indoor"
    first = client.request([location], synchronous=True, timeout=5)
    assert first.success, first.message
    time.sleep(3.5)  # /wslow reported applying it, and is silent until 6.4 s after that
    second = client.request(
        ["Indoor" if location == "Outdoor" else "Outdoor"], synchronous=True, timeout=5
    )
    assert second.success, second.message
    counts = [settled(watch, result.epoch)["nodes"] for result in (first, second)]
    stop(watch, hosting, slow)
    assert "/whosted" in second.acknowledged and "/wslow" in second.acknowledged
    assert counts == [len(first.acknowledged), len(second.acknowledged)], watch.output()
