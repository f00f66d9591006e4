"""A command is over within its timeout (plus the client's 2 s margin), and the manager
never starts a command whose caller has given up (issue 24, item 6)."""

from __future__ import annotations

import signal
import threading
import time

from contextros.ros import LayerClient
from contextros.ros.client import REPLY_MARGIN
from tests.ros.processes import ProcessGroup
from tests.ros.system import LIVENESS, settle, start_system, wait_registry
from tests.ros.test_cli import contextros


def test_an_atomic_command_whose_manager_dies_ends_within_its_timeout(
    client: LayerClient, processes: ProcessGroup
) -> None:
    voter = processes.participant("d1")
    manager = processes.manager("--liveness-timeout", "5")
    client.wait_for_manager(15.0)
    wait_registry(client, lambda r: len(r.participants) == 1 and not r.recovering)
    settle(client, "Indoor")
    voter.signal(signal.SIGSTOP)  # it cannot vote: the vote stays open until the kill
    threading.Timer(1.5, manager.signal, args=(signal.SIGKILL,)).start()
    started = time.monotonic()
    done = contextros("activate", "Night", "--atomic", "--timeout", "2")
    took = time.monotonic() - started
    # Before: 3 attempts of 2 x 2 s + 2 s, 18 s. Exit status 1: the outcome is unknown.
    assert done.returncode == 1, done
    assert "unknown" in done.stderr, done.stderr
    assert took < 2 + REPLY_MARGIN + 2.5, f"took {took:.1f} s (the command starts in ~1 s)"
    voter.signal(signal.SIGCONT)


def test_a_command_waiting_past_its_timeout_is_refused_never_executed(
    client: LayerClient, processes: ProcessGroup
) -> None:
    system = start_system(processes, client, ["w1"])
    before = settle(client, "Indoor")
    system.manager.signal(signal.SIGKILL)
    system.manager.wait_exit()
    # The new manager listens 10 s before deciding anything: the command waits meanwhile
    # (the window outlasts the discovery of the new manager on a loaded machine).
    launched = time.monotonic()
    processes.manager("--liveness-timeout", LIVENESS, "--recovery-window", "10", name="m2")
    client.wait_for_manager(15.0)
    assert client.query().recovering
    assert time.monotonic() - launched < 8.0, "the manager was found too late to test this"
    started = time.monotonic()
    result = client.request(["Night"], synchronous=True, timeout=1)
    took = time.monotonic() - started
    assert not result.success, result.message
    assert "not started within the command's timeout (1 s)" in result.message, result.message
    assert took < 1 + REPLY_MARGIN, f"took {took:.1f} s"
    recovered = wait_registry(client, lambda r: not r.recovering, 15.0, what="recovery")
    time.sleep(0.3)
    after = client.query()
    assert "Night" not in after.active_layers, f"executed after its caller gave up: {after}"
    assert after.epoch == recovered.epoch > before.epoch
