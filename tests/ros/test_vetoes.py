"""Application vetoes on atomic activations (issue 24): asked once per proposal, off the
node's executor, and every node that says no is named."""

from __future__ import annotations

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import LIVENESS, settle, wait_registry
from tests.ros.test_cli import contextros


def start(processes: ProcessGroup, client: LayerClient, nodes: dict[str, list[str]]) -> None:
    for name, options in nodes.items():
        processes.participant(name, *options)
    processes.manager("--liveness-timeout", LIVENESS)
    client.wait_for_manager(15.0)
    wait_registry(
        client,
        lambda r: len(r.participants) == len(nodes) and not r.recovering,
        what="participants registered",
    )


def test_a_slow_veto_is_asked_once_and_its_node_stays_live(
    client: LayerClient, processes: ProcessGroup
) -> None:
    # The veto thinks 1.5 s, longer than the manager's liveness bound (1 s): the node's
    # heartbeats must go on meanwhile.
    start(processes, client, {"s1": ["--veto-sleep", "1.5"], "s2": []})
    settle(client, "Indoor")
    result = client.request(["Night"], atomic=True, timeout=5)
    assert result.success, result.message
    assert result.acknowledged == ("/s1", "/s2")
    s1 = next(c for c in processes.children if c.name == "s1")
    calls = [e for e in s1.events if e["event"] == "veto-called" and e["epoch"] == result.epoch]
    assert len(calls) == 1, f"the veto was asked {len(calls)} times about one proposal"


def test_every_node_that_says_no_is_named(client: LayerClient, processes: ProcessGroup) -> None:
    start(
        processes,
        client,
        {"n1": ["--veto", "battery low"], "n2": ["--veto", "arm busy"], "n3": []},
    )
    before = settle(client, "Indoor")
    result = client.request(["Night"], atomic=True, timeout=5)
    assert not result.success
    assert result.not_acknowledged == ("/n1", "/n2"), result.message
    assert "/n1 vetoed: battery low" in result.message
    assert "/n2 vetoed: arm busy" in result.message
    assert (result.epoch, result.active) == (before.epoch, ("Indoor",))
    # On the command line: a failure on stderr, nothing that reads as a success on stdout.
    done = contextros("activate", "Night", "--atomic", "--timeout", "5")
    assert done.returncode == 1, done
    assert "acknowledged" not in done.stdout, done.stdout
    assert "/n1 vetoed: battery low" in done.stderr and "/n2 vetoed: arm busy" in done.stderr
