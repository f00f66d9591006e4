"""The `contextros` command against a running manager: exit statuses and messages."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup, reserve_domain_id
from tests.ros.system import RunningSystem, settle, start_system


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        yield start_system(group, client, ["cli1", "cli2"])
    finally:
        group.kill_all()


def contextros(*args: str, domain: str | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if domain is not None:
        env["ROS_DOMAIN_ID"] = domain
    return subprocess.run(
        [sys.executable, "-m", "contextros", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )


def test_activate_sync_reports_the_acknowledging_nodes(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client)
    done = contextros("activate", "Indoor", "Night", "--sync", "--timeout", "5", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["success"] and answer["active"] == ["Indoor", "Night"]
    assert answer["acknowledged"] == ["/cli1", "/cli2"]


def test_unknown_layer_exits_non_zero_with_the_managers_message(system: RunningSystem) -> None:
    refused = contextros("switch", "--on", "Underwater", "--off", "Night")
    assert refused.returncode == 1
    assert "unknown layer 'Underwater'" in refused.stderr
    assert "nothing changed" in refused.stderr
    # The manager logs every refusal (issue 12), after answering.
    deadline = time.monotonic() + 5
    while "refused: unknown layer 'Underwater'" not in system.manager.output():
        assert time.monotonic() < deadline, system.manager.output()
        time.sleep(0.05)


def test_status_shows_layers_nodes_and_epochs(system: RunningSystem, client: LayerClient) -> None:
    shown = contextros("status")
    assert shown.returncode == 0, shown.stderr
    epoch = client.query().epoch
    assert f"epoch {epoch}" in shown.stdout
    assert "/cli1" in shown.stdout and "/cli2" in shown.stdout
    assert "location" in shown.stdout  # the Indoor/Outdoor group
    data = json.loads(contextros("status", "--json").stdout)
    assert {p["node"] for p in data["participants"]} == {"/cli1", "/cli2"}
    assert all(p["applied_epoch"] == epoch for p in data["participants"])


def test_watch_streams_switches_with_latency(
    system: RunningSystem, client: LayerClient, processes: ProcessGroup
) -> None:
    watch = processes.start("watch", ["-m", "contextros", "watch", "--count", "1", "--json"])
    current = client.query().epoch
    watch.wait_for(
        lambda events: (
            {e.get("node") for e in events if e["event"] == "node"} >= {"/cli1", "/cli2"}
            and any(e["event"] == "current" for e in events)
        ),
        10,
        "the current state and both nodes",
    )
    night = "Night" in client.query().active_layers
    result = client.request(
        [] if night else ["Night"], ["Night"] if night else [], synchronous=True
    )
    assert result.success, result.message
    assert watch.wait_exit(10) == 0
    switches = [(e["event"], e["epoch"]) for e in watch.events if "epoch" in e]
    assert switches == [("current", current), ("state", result.epoch), ("applied", result.epoch)]
    applied = watch.events[-1]
    assert applied["nodes"] == 2 and 0 <= applied["latency_ms"] < 1000
    replayed = next(e for e in watch.events if e["event"] == "current")
    assert replayed["replayed"] is True and "delivery_ms" not in replayed  # an age instead
    fresh = next(e for e in watch.events if e["event"] == "state")
    assert fresh["replayed"] is False and 0 <= fresh["delivery_ms"] < 1000


def test_a_deactivation_that_changes_nothing_says_so(system: RunningSystem) -> None:
    done = contextros("deactivate", "Night", "--sync")
    assert done.returncode == 0, done.stderr
    again = contextros("deactivate", "Night", "--sync")
    assert again.returncode == 0, again.stderr
    assert "no change" in again.stdout and "acknowledged by" not in again.stdout


def test_no_manager_exits_with_status_3() -> None:
    empty_domain = str(reserve_domain_id(int(os.environ["ROS_DOMAIN_ID"]) + 1))
    lonely = contextros("activate", "Night", "--wait-manager", "0.5", domain=empty_domain)
    assert lonely.returncode == 3
    assert "no Layer manager" in lonely.stderr


def test_ctrl_c_while_waiting_for_the_manager_exits_130_quietly() -> None:
    """The terminal's SIGINT reaches the command and its ROS client (a child: see
    contextros.cli.answered_in_child); the command says what that means, no traceback."""
    empty_domain = str(reserve_domain_id(int(os.environ["ROS_DOMAIN_ID"]) + 1))
    command = subprocess.Popen(
        [sys.executable, "-m", "contextros", "activate", "Night", "--wait-manager", "30"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, ROS_DOMAIN_ID=empty_domain),
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )
    try:
        deadline = time.monotonic() + 20
        while not _children(command.pid):  # the client's child exists: it is waiting
            assert time.monotonic() < deadline, "no ROS client process was started"
            time.sleep(0.05)
        time.sleep(0.5)  # inside rclpy by now
        os.killpg(command.pid, signal.SIGINT)
        _, stderr = command.communicate(timeout=20)
    finally:
        if command.poll() is None:
            os.killpg(command.pid, signal.SIGKILL)
    assert command.returncode == 130, stderr
    assert "interrupted; whether it was carried out is unknown" in stderr
    assert "Traceback" not in stderr, stderr


def _children(pid: int) -> list[str]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return path.read_text().split() if path.exists() else []


def test_manager_refuses_a_damaged_state_file(tmp_path: Path) -> None:
    """Each damage one message naming the file and what is wrong (tests/protocol/manager/
    test_memory.py tries many more on the parser); run at once, in parallel processes."""
    damages = {
        "{ not json": "not JSON at line 1 column 3",
        bytes([0x7B, 0xFF, 0x7D]): "not UTF-8 at byte 1",
        "[]": "not a JSON object but a list",
        '{"epoch": 3}': "missing field 'active'",
        None: "it is a directory",
    }
    running = []
    for index, (content, message) in enumerate(damages.items()):
        damaged = tmp_path / f"state{index}.json"
        if content is None:
            damaged.mkdir()
        else:
            damaged.write_bytes(content.encode() if isinstance(content, str) else content)
        command = [sys.executable, "-m", "contextros", "manager", "--state-file", str(damaged)]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        running.append((damaged, message, process))
    for damaged, message, process in running:
        try:
            _, err = process.communicate(timeout=60)
        finally:
            process.kill()
        stderr = err.decode()
        assert process.returncode == 1, stderr
        assert f"contextros manager: {damaged}: not a ContextROS state file: {message}" in stderr
        assert "Traceback" not in stderr, stderr


def test_sync_fails_unless_the_expected_nodes_applied_it(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client)
    missing = contextros(
        "activate", "Night", "--sync", "--timeout", "0.5", "--expect", "/cli1", "/robot_arm"
    )
    assert missing.returncode == 1, missing.stdout
    assert "expected node /robot_arm did not apply it" in missing.stderr
    counted = contextros("deactivate", "Night", "--sync", "--expect-count", "2")
    assert counted.returncode == 0, counted.stderr
    too_many = contextros("activate", "Night", "--sync", "--timeout", "0.5", "--expect-count", "3")
    assert too_many.returncode == 1
    assert "applied by 2 node(s), 3 expected" in too_many.stderr
    usage = contextros("activate", "Night", "--expect", "/cli1")
    assert usage.returncode == 2 and "need --sync or --atomic" in usage.stderr


def test_the_client_api_has_one_default_and_exports_its_errors(
    system: RunningSystem, client: LayerClient
) -> None:
    """Issue 12: ActivationFailed from contextros.ros, one default (asynchronous, as the CLI
    without --sync) for request, request_async, activate and deactivate."""
    import inspect

    from contextros import protocol
    from contextros.ros import ActivationFailed, ActivationResult, ManagerError

    assert ActivationFailed is protocol.ActivationFailed and issubclass(
        ActivationFailed, ManagerError
    )
    defaults = {
        name: inspect.signature(getattr(LayerClient, name)).parameters["synchronous"].default
        for name in ("request", "request_async", "activate", "deactivate")
    }
    assert set(defaults.values()) == {False}, defaults
    with pytest.raises(ActivationFailed, match="unknown layer 'Underwater'"):
        client.activate("Underwater")
    settle(client)
    result = client.activate("Night", synchronous=True, timeout=5)
    assert isinstance(result, ActivationResult) and result.active[-1] == "Night"
