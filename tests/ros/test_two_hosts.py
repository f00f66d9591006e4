"""Two hosts (network namespaces joined by an emulated link): the manager and a client on
one, the context nodes on the other; then loss, delay and a partition (issue 10).

With 30% loss and 50 ms each way, the landed protocol dropped the remote nodes as silent
and its synchronous activations "succeeded" acknowledged by the local node only (0 of 30
reached all nodes). These tests hold the promises on such a link.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import pytest

from tests.netns.hosts import TwoHosts, available
from tests.ros.processes import Child

pytestmark = pytest.mark.skipif(bool(available()), reason=available() or "")

NODES = ["/far1", "/far2", "/far3"]


class Remote:
    """The client process on the manager's host, driven line by line."""

    def __init__(self, child: Child) -> None:
        self.child = child
        child.wait_for(lambda events: any(e["event"] == "ready" for e in events), 30, "client")

    def ask(self, **command: Any) -> dict[str, Any]:
        seen = len(self.child.events)
        self.child.send(json.dumps(command))
        return self.child.wait_for(
            lambda events: events[seen] if len(events) > seen else None, 60.0, "answer"
        )

    def sync(self, layer: str, **options: Any) -> dict[str, Any]:
        return self.ask(op="request", activate=[layer], synchronous=True, **options)

    def registry(self) -> dict[str, Any]:
        return self.ask(op="query")

    def wait_registry(self, predicate: Any, timeout: float, what: str) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            registry = self.registry()
            if registry["event"] == "registry" and predicate(registry):
                return registry
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {what}: {registry}")
            time.sleep(0.2)


@pytest.fixture
def hosts() -> Iterator[TwoHosts]:
    with TwoHosts(seed=10) as two:
        yield two


def start(hosts: TwoHosts) -> tuple[Remote, dict[str, Child], Child]:
    manager_side, node_side = hosts.group("a"), hosts.group("b")
    manager = manager_side.manager()
    nodes = {name: node_side.participant(name.strip("/")) for name in NODES}
    remote = Remote(manager_side.start("client", ["tests/netns/remote_client.py"]))
    remote.wait_registry(
        lambda r: r["epoch"] >= 1 and sorted(r["participants"]) == NODES,
        timeout=40,
        what="the far nodes registered across the link",
    )
    return remote, nodes, manager


def test_synchronous_activations_reach_every_far_node_over_a_lossy_link(
    hosts: TwoHosts,
) -> None:
    remote, _, manager = start(hosts)
    clean = remote.sync("Indoor", timeout=5.0, expect_count=3)
    assert clean["success"] and clean["acknowledged"] == NODES, clean["message"]
    hosts.impair(loss=0.3, delay=0.05)
    answers = [
        remote.sync("Outdoor" if i % 2 else "Indoor", timeout=5.0, expect_count=3)
        for i in range(12)
    ]
    answers += [
        remote.ask(
            op="request",
            activate=["Outdoor" if i % 2 else "Indoor"],
            atomic=True,
            timeout=5.0,
            expect_count=3,
        )
        for i in range(6)
    ]
    failures = [a["message"] for a in answers if not a["success"]]
    assert failures == [], failures
    assert all(a["acknowledged"] == NODES for a in answers)
    registry = remote.registry()
    assert registry["dropped"] == [], "no node dropped as silent on a lossy link"
    assert "dropped" not in manager.output()
    link = hosts.stats()
    assert link["dropped"] > 20, f"the link really lost frames: {link}"


def test_partition_fails_honestly_and_heals(hosts: TwoHosts) -> None:
    remote, nodes, _ = start(hosts)
    before = remote.sync("Indoor", timeout=5.0, expect_count=3)
    assert before["success"], before["message"]
    hosts.cut()
    cut_at = time.monotonic()
    # Asked to reach three nodes, the manager (which may not have dropped them yet) says no.
    cut_off = remote.sync("Night", timeout=1.0, expect_nodes=NODES)
    assert not cut_off["success"]
    assert cut_off["not_acknowledged"] == NODES, cut_off["message"]
    # An atomic activation cannot gather the votes: aborted, nothing changed anywhere.
    vote = remote.ask(op="request", activate=["Outdoor"], atomic=True, timeout=0.5)
    assert not vote["success"] and "aborted, nothing changed" in vote["message"], vote
    assert vote["active"] == ["Indoor", "Night"]
    # Each far node knows it is cut off (liveness bound 3 s), and the manager drops them.
    for child in nodes.values():
        # After the cut: a node may also have lost the manager at start-up, before the far
        # side's discovery went through.
        lost = child.wait_for(
            lambda events: next(
                (e for e in events if e["event"] == "manager-lost" and e["t"] > cut_at), None
            ),
            10,
        )
        assert lost["t"] - cut_at >= 1.5, "not before the liveness bound (3 s), give or take"
    remote.wait_registry(lambda r: sorted(r["dropped"]) == NODES, 10, "far nodes dropped")
    # With every node dropped, an activation would be refused (no live node implements the
    # layer); a deactivation is accepted, and reaching nobody is a failure, not a success.
    nobody = remote.ask(op="request", deactivate=["Night"], synchronous=True, timeout=1.0)
    assert not nobody["success"] and "reached no node" in nobody["message"], nobody
    hosts.heal()
    for child in nodes.values():
        child.wait_for(
            lambda events: any(e["event"] == "manager-found" and e["t"] > cut_at for e in events),
            15,
        )
    healed = remote.wait_registry(
        lambda r: sorted(r["participants"]) == NODES and r["dropped"] == [], 15, "rejoined"
    )
    for child in nodes.values():
        child.wait_applied(healed["epoch"], timeout=10)
        assert "Outdoor" not in child.applied()[-1]["active"], "the aborted one never applied"
    after = remote.sync("Indoor", timeout=5.0, expect_nodes=NODES)
    assert after["success"] and after["acknowledged"] == NODES, after["message"]
