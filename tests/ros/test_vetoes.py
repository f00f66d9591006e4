"""Application vetoes on atomic activations (issue 24): asked once per proposal, off the
node's executor, and every node that says no is named."""

from __future__ import annotations

import re
import signal
import textwrap
import threading
import time
from pathlib import Path

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


def test_a_node_stopped_during_its_veto_waits_for_it_before_exiting(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """A veto is user code on a thread of its own: a node stopped (SIGTERM) while it thinks
    lets it answer before the interpreter goes (as the C++ participant does)."""
    start(processes, client, {"t1": ["--veto-sleep", "1.5"], "t2": []})
    t1 = next(c for c in processes.children if c.name == "t1")
    asking = threading.Thread(
        target=lambda: client.request(["Night"], atomic=True, timeout=5), daemon=True
    )
    asking.start()
    t1.wait_for(lambda events: any(e["event"] == "veto-called" for e in events), 10, "a veto")
    t1.signal(signal.SIGTERM)
    t1.wait_exit(10)
    assert any(e["event"] == "veto-answered" for e in t1.events), t1.output()
    assert "Traceback" not in t1.output(), t1.output()
    asking.join(10)


def test_a_veto_that_fails_says_no_and_is_logged_in_python_and_cpp(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """docs/cpp.md: an exception from a veto is logged (it was only in the manager's answer)."""
    start(processes, client, {"x_py": ["--veto", "raise"]})
    cpp = processes.cpp_participant("x_cxx", "--veto-throw", "veto exploded")
    wait_registry(client, lambda r: len(r.participants) == 2, what="both nodes")
    result = client.request(["Night"], atomic=True, timeout=5)
    assert not result.success and result.not_acknowledged == ("/x_cxx", "/x_py"), result.message
    assert "veto exploded" in result.message
    py = next(c for c in processes.children if c.name == "x_py")
    for node in (py, cpp):
        deadline = time.monotonic() + 5
        while "voting no" not in node.output() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert re.search(r"veto.*failed.*veto exploded.*voting no", node.output()), node.output()


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


def test_the_veto_example_of_the_protocol_docs_refuses_with_its_reason(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    """docs/protocol.md's `veto_node.py`, run as it is: a veto reads the proposal's fields."""
    docs = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text()
    found = re.search(r"```python\n( *# veto_node\.py\n.*?) *```", docs, re.S)
    assert found is not None, "docs/protocol.md has no veto_node.py example"
    script = tmp_path / "veto_node.py"
    script.write_text(textwrap.dedent(found.group(1)), encoding="utf-8")
    processes.start("veto_node", [str(script)])
    processes.participant("other")
    processes.manager("--liveness-timeout", LIVENESS)
    client.wait_for_manager(15.0)
    wait_registry(
        client,
        lambda r: {p.node for p in r.participants} == {"/veto_node", "/other"} and not r.recovering,
        what="the example's node registered",
    )
    result = client.request(["Night"], atomic=True, timeout=5)
    assert not result.success
    assert result.not_acknowledged == ("/veto_node",), result.message
    assert "/veto_node vetoed: battery low" in result.message, result.message
    log = "\n".join(next(c for c in processes.children if c.name == "veto_node").lines)
    assert "Traceback" not in log and "failed" not in result.message, log
