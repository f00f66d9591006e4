"""`contextros watch`'s logic, driven in every order the messages may arrive in.

The flaky `tests/ros/test_cli.py::test_watch_streams_switches_with_latency` (issue 12)
saw `nodes == 1` with two acknowledging nodes: a node's status for the new epoch reached
the watch before the state message itself, and the old code counted only the nodes
still pending when the state arrived. The code was wrong, not the test.
"""

from __future__ import annotations

from contextros.cli.watching import SwitchWatch


def watch_with_two_nodes() -> SwitchWatch:
    watch = SwitchWatch(started=90.0)  # it has listened long enough to know every node
    watch.state(4, ["Indoor"], "r", "", published=50.0, wall=100.0, now=1.0)
    for node in ("/a", "/b"):
        watch.status(node, 4, leaving=False, wall=100.0, now=1.0)
    return watch


def test_a_status_that_overtakes_its_state_still_counts_the_node() -> None:
    watch = watch_with_two_nodes()
    early = watch.status("/a", 5, leaving=False, wall=101.0, now=2.0)
    assert early == []
    records = watch.state(5, ["Night"], "r", "", published=100.999, wall=101.001, now=2.0)
    assert [r["event"] for r in records] == ["state"]
    records = watch.status("/b", 5, leaving=False, wall=101.002, now=2.0)
    assert records == [{"event": "applied", "epoch": 5, "nodes": 2, "latency_ms": 3.0}]


def test_both_statuses_before_the_state_report_applied_by_two_at_once() -> None:
    watch = watch_with_two_nodes()
    watch.status("/a", 5, leaving=False, wall=101.0, now=2.0)
    watch.status("/b", 5, leaving=False, wall=101.0, now=2.0)
    records = watch.state(5, ["Night"], "r", "", published=100.999, wall=101.001, now=2.0)
    assert [r["event"] for r in records] == ["state", "applied"]
    assert records[1]["nodes"] == 2


def test_the_replayed_current_state_carries_its_age_not_a_latency() -> None:
    watch = SwitchWatch(started=1000.0)
    (record,) = watch.state(3, [], "m", "", published=988.314, wall=1000.0, now=0.0)
    assert record["event"] == "current" and record["replayed"] is True
    assert record["age_s"] == 11.686 and "delivery_ms" not in record
    (fresh,) = watch.state(4, ["A"], "r", "", published=1000.5, wall=1000.502, now=1.0)
    assert fresh["replayed"] is False and fresh["delivery_ms"] == 2.0
    assert watch.tick(wall=1002.9) == []
    (applied,) = watch.tick(wall=1003.0)
    assert applied["nodes"] == 0  # nobody live, now that the watch would know


def test_a_switch_in_the_first_seconds_waits_for_the_nodes_not_heard_yet() -> None:
    """Issue 25: a watch started 1 s before an activation printed `applied by all 0 live
    node(s)` while 2 nodes acknowledged: discovery had not matched their statuses yet."""
    watch = SwitchWatch(started=1000.0)
    watch.state(1, [], "m", "", published=990.0, wall=1000.1, now=0.1)
    (state,) = watch.state(2, ["A"], "r", "", published=1001.0, wall=1001.001, now=1.0)
    assert state["event"] == "state", "no node known yet: not applied by all 0"
    assert watch.status("/a", 2, leaving=False, wall=1001.5, now=1.5) == [
        {"event": "node", "node": "/a"}
    ]
    assert watch.status("/b", 1, leaving=False, wall=1001.6, now=1.6)[0]["event"] == "node"
    assert watch.tick(wall=1003.5) == [], "/b has not applied it"
    (applied,) = watch.status("/b", 2, leaving=False, wall=1003.6, now=3.6)
    assert applied == {"event": "applied", "epoch": 2, "nodes": 2, "latency_ms": 2600.0}


def test_a_node_leaving_is_not_waited_for() -> None:
    watch = watch_with_two_nodes()
    watch.state(5, ["Night"], "r", "", published=101.0, wall=101.0, now=2.0)
    assert watch.status("/a", 5, leaving=False, wall=101.0, now=2.0) == []
    records = watch.status("/b", 4, leaving=True, wall=101.0, now=2.0)
    assert records[0] == {"event": "node-left", "node": "/b"}
    assert records[1]["event"] == "applied" and records[1]["nodes"] == 1


def test_a_node_counts_until_the_managers_liveness_bound() -> None:
    """The watch drops a silent node when the manager does (3 s), not earlier: a node
    silent for 2.5 s (ten lost heartbeats on a lossy link) must still apply the switch."""
    watch = watch_with_two_nodes()  # both heard at now=1.0
    records = watch.state(5, ["Night"], "r", "", published=101.0, wall=101.0, now=3.5)
    assert records[-1]["event"] == "state"
    watch.status("/a", 5, leaving=False, wall=101.01, now=3.5)
    records = watch.status("/b", 5, leaving=False, wall=101.02, now=3.5)
    assert records == [{"event": "applied", "epoch": 5, "nodes": 2, "latency_ms": 20.0}]


def test_a_counted_watch_ends_once_its_last_switch_is_reported() -> None:
    watch = SwitchWatch(started=1000.0)
    watch.state(1, [], "m", "", published=990.0, wall=1000.1, now=0.1)  # the current one
    watch.state(2, ["A"], "r", "", published=1001.0, wall=1001.001, now=1.0)
    watch.status("/a", 2, leaving=False, wall=1001.1, now=1.1)
    assert not watch.finished(1, now=3.5, wall=1002.9), "its switch is not reported yet"
    assert [r["event"] for r in watch.tick(wall=1003.0)] == ["applied"]
    assert watch.finished(1, now=3.6, wall=1003.0)


def test_a_refusal_is_reported_and_a_newer_epoch_does_not_make_it_applied() -> None:
    """Issue: epoch 1034, refused by both nodes, was printed `applied by all 2` once they
    applied 1035 (an applied epoch at least as new counted)."""
    watch = watch_with_two_nodes()
    watch.state(5, [], "r", "", published=101.0, wall=101.0, now=2.0)
    for node in ("/a", "/b"):
        (refused, *rest) = watch.status(
            node, 4, leaving=False, wall=101.01, now=2.0, failed_epoch=5, error="epoch 5: no"
        )
        assert refused == {"event": "refused", "epoch": 5, "node": node, "error": "epoch 5: no"}
    (outcome,) = rest
    assert outcome["event"] == "not-applied" and outcome["refused_by"] == ["/a", "/b"]
    assert outcome["applied_by"] == []
    watch.state(6, ["A"], "r", "", published=102.0, wall=102.0, now=3.0)
    watch.status("/a", 6, leaving=False, wall=102.01, now=3.0, failed_epoch=5, error="epoch 5: no")
    (applied,) = watch.status(
        "/b", 6, leaving=False, wall=102.02, now=3.0, failed_epoch=5, error="epoch 5: no"
    )
    assert applied["event"] == "applied" and applied["epoch"] == 6


def test_a_refusal_that_overtakes_its_state_is_reported_with_it() -> None:
    watch = watch_with_two_nodes()
    watch.status("/a", 4, leaving=False, wall=101.0, now=2.0, failed_epoch=5, error="epoch 5: x")
    records = watch.state(5, [], "r", "", published=100.99, wall=101.01, now=2.0)
    assert [r["event"] for r in records] == ["state", "refused"]


def test_a_node_going_on_to_a_newer_epoch_skipped_the_one_it_never_applied() -> None:
    watch = watch_with_two_nodes()
    watch.state(5, ["A"], "r", "", published=101.0, wall=101.0, now=2.0)
    watch.status("/a", 5, leaving=False, wall=101.0, now=2.0)
    watch.state(6, ["B"], "r", "", published=101.1, wall=101.1, now=2.1)
    records = watch.status("/b", 6, leaving=False, wall=101.2, now=2.2)
    assert records[0] == {"event": "skipped", "epoch": 5, "node": "/b", "went_to": 6}
    assert records[1]["event"] == "not-applied" and records[1]["skipped_by"] == ["/b"]
    assert records[1]["applied_by"] == ["/a"]


def test_the_registry_decides_who_is_live_with_the_nodes_they_host() -> None:
    """The manager's liveness bound may be longer than 3 s, and it counts the nodes a
    participant hosts: the watch counts the nodes the manager's registry lists."""
    watch = SwitchWatch(started=100.0)
    watch.state(1, [], "m", "", published=90.0, wall=100.0, now=0.0)
    watch.status("/a", 1, leaving=False, wall=100.1, now=0.1, hosted=("/h",))
    watch.status("/slow", 1, leaving=False, wall=100.1, now=0.1)
    assert watch.registry({"/a": ("/h",), "/slow": ()}, asked=0.5, wall=100.6) == []
    watch.state(2, ["A"], "r", "", published=105.0, wall=105.0, now=5.0)  # /slow silent 4.9 s
    watch.status("/a", 2, leaving=False, wall=105.01, now=5.01, hosted=("/h",))
    (applied,) = watch.status("/slow", 2, leaving=False, wall=105.02, now=5.02)
    assert applied["nodes"] == 3 and applied["latency_ms"] == 20.0
    watch.state(3, ["B"], "r", "", published=106.0, wall=106.0, now=6.0)
    watch.status("/a", 3, leaving=False, wall=106.01, now=6.01, hosted=("/h",))
    dropped, applied = watch.registry({"/a": ("/h",)}, asked=6.5, wall=106.6)
    assert dropped == {"event": "node-left", "node": "/slow", "dropped": True}
    assert applied["event"] == "applied" and applied["nodes"] == 2


def test_a_counted_watch_waits_the_liveness_bound_then_names_who_never_answered() -> None:
    """CI: under load one node's status came more than 2 s after the switch, and the watch
    ended without a word on it. It waits as long as the manager would, then says who."""
    watch = watch_with_two_nodes()  # both heard at now=1.0
    watch.state(5, ["Night"], "r", "", published=101.0, wall=101.0, now=3.5)
    watch.status("/a", 5, leaving=False, wall=101.01, now=3.5)
    watch.status("/b", 4, leaving=False, wall=101.4, now=3.9)  # a heartbeat, still on 4
    assert not watch.finished(1, now=3.5 + 2.1, wall=103.1)
    records = watch.status("/b", 5, leaving=False, wall=103.2, now=5.7)
    assert [r["event"] for r in records] == ["applied"]
    assert watch.finished(1, now=5.7, wall=103.2)

    watch = watch_with_two_nodes()
    watch.state(5, ["Night"], "r", "", published=101.0, wall=101.0, now=3.5)
    watch.status("/a", 5, leaving=False, wall=101.01, now=3.5)
    assert watch.finished(1, now=3.5 + watch.liveness + 1.1, wall=106.0)
    assert watch.unsettled() == [{"event": "unsettled", "epoch": 5, "nodes": 2, "pending": ["/b"]}]
    assert watch.unsettled() == []
