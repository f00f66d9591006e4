"""The CLI's daemon with a real manager and real participants: the first command starts it,
the next ones go through it (no rclpy in the command's process), with the same answers,
exit statuses and messages as without it; bad requests on its socket change nothing."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from contextros.cli.daemon import client
from contextros.cli.daemon.place import DaemonPlace, daemon_place, environment_key
from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import RunningSystem, settle, start_system


@pytest.fixture(scope="module")
def runtime() -> Iterator[Path]:
    """A directory of the module's own (short: a socket's path has at most 107 bytes)."""
    directory = Path(tempfile.mkdtemp(prefix="crd-"))
    try:
        yield directory
    finally:
        contextros("daemon", "stop", "--all", runtime=directory)
        shutil.rmtree(directory, ignore_errors=True)


@pytest.fixture(scope="module")
def system(client: LayerClient, runtime: Path) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        yield start_system(group, client, ["dm1", "dm2"])
    finally:
        group.kill_all()


def contextros(
    *args: str, runtime: Path, daemon: bool = True, python: tuple[str, ...] = ()
) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, CONTEXTROS_RUNTIME_DIR=str(runtime))
    if daemon:
        env.pop("CONTEXTROS_NO_DAEMON", None)
    return subprocess.run(
        [sys.executable, *python, "-m", "contextros", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )


def served(*args: str, runtime: Path) -> subprocess.CompletedProcess[str]:
    """Run a command that the daemon must answer: its process never imports rclpy."""
    done = contextros(*args, runtime=runtime, python=("-X", "importtime"))
    imported = [line.rpartition("|")[2].strip() for line in done.stderr.splitlines()]
    assert not [m for m in imported if m.split(".")[0] == "rclpy"], "it asked the manager itself"
    done.stderr = "\n".join(line for line in done.stderr.splitlines() if "import time:" not in line)
    return done


def daemon_running(runtime: Path) -> bool:
    return contextros("daemon", "status", runtime=runtime).returncode == 0


def wait_until(predicate: object, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():  # type: ignore[operator]
        assert time.monotonic() < deadline, what
        time.sleep(0.1)


@pytest.fixture(scope="module")
def daemon(system: RunningSystem, runtime: Path) -> Path:
    """The first command answers by itself and starts the daemon for the next ones."""
    assert not daemon_running(runtime)
    first = contextros("status", "--json", runtime=runtime)
    assert first.returncode == 0, first.stderr
    wait_until(lambda: daemon_running(runtime), 20, "the first command started no daemon")
    return runtime


def test_commands_through_the_daemon_answer_as_without_it(
    daemon: Path, client: LayerClient
) -> None:
    settle(client)
    done = served("activate", "Indoor", "--sync", "--json", "--reason", "by daemon", runtime=daemon)
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["success"] and answer["active"] == ["Indoor"]
    assert answer["acknowledged"] == ["/dm1", "/dm2"]
    registry = client.query()
    assert registry.reason == "by daemon"
    # The requester is the command's process, not the daemon's.
    shown = contextros("daemon", "status", runtime=daemon).stdout
    daemon_pid = shown.split()[1]
    assert re.fullmatch(r".+@pid\d+", registry.requester), registry.requester
    assert not registry.requester.endswith(f"@pid{daemon_pid}"), (registry.requester, shown)
    through = json.loads(served("status", "--json", runtime=daemon).stdout)
    direct = contextros("status", "--json", "--no-daemon", runtime=daemon)
    assert direct.returncode == 0, direct.stderr
    alone = json.loads(direct.stdout)
    for key in ("epoch", "active", "requester", "reason", "layers"):
        assert through[key] == alone[key], key
    assert {p["node"] for p in through["participants"]} == {"/dm1", "/dm2"}
    table = served("status", runtime=daemon)
    assert table.returncode == 0 and "/dm1" in table.stdout and "LAYER" in table.stdout


def test_refusals_keep_their_exit_statuses_and_messages(daemon: Path) -> None:
    refused = served("switch", "--on", "Underwater", "--off", "Night", runtime=daemon)
    assert refused.returncode == 1
    assert "unknown layer 'Underwater'" in refused.stderr and "nothing changed" in refused.stderr
    invalid = served("activate", "Bad Name!", runtime=daemon)
    assert invalid.returncode == 1 and "invalid command" in invalid.stderr, invalid.stderr
    nobody = served(
        "status", "--namespace", "/nobody_here", "--wait-manager", "0.5", runtime=daemon
    )
    assert nobody.returncode == 3, nobody.stderr
    assert "no Layer manager answers on /nobody_here/contextros/query " in nobody.stderr


def test_concurrent_commands_are_all_answered(daemon: Path) -> None:
    with ThreadPoolExecutor(6) as pool:
        runs = list(pool.map(lambda _: served("status", "--json", runtime=daemon), range(6)))
    for done in runs:
        assert done.returncode == 0, done.stderr
        assert {p["node"] for p in json.loads(done.stdout)["participants"]} == {"/dm1", "/dm2"}


def test_bad_requests_on_the_socket_are_refused_and_the_daemon_serves_on(daemon: Path) -> None:
    place = DaemonPlace(daemon, environment_key(dict(os.environ)))
    # Not a JSON object: the connection is dropped. A JSON object: refused, saying why.
    for line in (b"not json\n", b"[1, 2]\n"):
        assert _exchange(place, line) is None
    bad = [
        b'{"protocol": 1, "command": "reboot"}\n',
        b'{"protocol": 2, "command": "ping"}\n',
        b'{"protocol": 1, "command": "activate", "namespace": null, "wait_manager": 1,'
        b' "on": "Indoor", "off": [], "expect": [], "sync": false, "atomic": false,'
        b' "timeout": 0, "expect_count": 0, "reason": "", "requester": ""}\n',
        b'{"protocol": 1, "command": "status", "namespace": "no/slash", "wait_manager": 1}\n',
        b'{"protocol": 1, "command": "status", "namespace": null, "wait_manager": 1e400}\n',
        b'{"protocol": 1, "command": "status", "wait_manager": 1}\n',
    ]
    for line in bad:
        answer = _exchange(place, line)
        assert answer is not None and answer["outcome"] == "refused", (line, answer)
        assert "invalid request" in str(answer["message"])
    # Too long, and a peer that sends half a request and goes: the connection is dropped.
    assert _exchange(place, b"{" + b" " * (70 * 1024)) is None
    assert _exchange(place, b'{"protocol": 1') is None
    done = served("status", "--json", runtime=daemon)
    assert done.returncode == 0, done.stderr


def _exchange(place: DaemonPlace, data: bytes) -> dict[str, object] | None:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as connection:
        connection.settimeout(10)
        connection.connect(str(place.socket))
        try:
            connection.sendall(data)
            connection.shutdown(socket.SHUT_WR)
            reply = b""
            while chunk := connection.recv(65536):
                reply += chunk
        except (BrokenPipeError, ConnectionResetError):
            return None
    return json.loads(reply) if reply else None


def test_stop_ends_the_daemon_and_the_next_command_answers_by_itself(daemon: Path) -> None:
    stopped = contextros("daemon", "stop", runtime=daemon)
    assert stopped.returncode == 0 and "stopped" in stopped.stdout, stopped.stdout
    assert not daemon_running(daemon)
    assert not list(daemon.glob("*.sock"))
    # The next command answers by itself and starts a daemon again, unless one was started
    # less than SPAWN_PAUSE ago (as if this one's start was long ago).
    for pid_file in daemon.glob("*.pid"):
        os.utime(pid_file, (0, 0))
    done = contextros("status", "--json", runtime=daemon)
    assert done.returncode == 0, done.stderr
    wait_until(lambda: daemon_running(daemon), 20, "no daemon started again")


def test_another_domain_reaches_no_daemon_of_this_one(daemon: Path) -> None:
    env = dict(os.environ, CONTEXTROS_RUNTIME_DIR=str(daemon))
    env["ROS_DOMAIN_ID"] = str((int(env.get("ROS_DOMAIN_ID", "0")) + 100) % 232)
    done = subprocess.run(
        [sys.executable, "-m", "contextros", "daemon", "status"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert done.returncode == 1 and "no daemon serves this environment" in done.stdout
    assert daemon_running(daemon)  # this domain's still serves


def test_a_daemon_stopped_while_it_starts_stops(
    system: RunningSystem, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`contextros activate X; contextros daemon stop` in a script: the daemon the first
    command started may still be starting when the stop comes; it is stopped all the same
    (here the stop comes right after the start, before the daemon even holds its lock)."""
    runtime = Path(tempfile.mkdtemp(prefix="crd-stop-"))
    monkeypatch.setenv("CONTEXTROS_RUNTIME_DIR", str(runtime))
    place = daemon_place()
    try:
        assert client.spawn(place)
        outcome = client.stop(place)
        assert outcome is not None and outcome[1], place.log.read_text()
        assert client.ping(place) is None
        time.sleep(1.0)
        assert client.ping(place) is None and not client.starting(place)
    finally:
        contextros("daemon", "stop", "--all", runtime=runtime)
        shutil.rmtree(runtime, ignore_errors=True)


def test_an_idle_daemon_stops_by_itself(system: RunningSystem) -> None:
    runtime = Path(tempfile.mkdtemp(prefix="crd-idle-"))
    try:
        started = contextros("daemon", "start", "--idle-timeout", "1", runtime=runtime)
        assert started.returncode == 0, started.stderr
        assert "serves" in started.stdout
        log = next(runtime.glob("*.log"))
        wait_until(lambda: not daemon_running(runtime), 15, f"it did not stop: {log.read_text()}")
        assert "idle for 1 s" in log.read_text()
    finally:
        contextros("daemon", "stop", "--all", runtime=runtime)
        shutil.rmtree(runtime, ignore_errors=True)


def test_a_daemon_whose_teardown_hangs_still_ends_and_logs_where() -> None:
    """Fast DDS can deadlock deleting a participant; the daemon's way out is bounded."""
    runtime = Path(tempfile.mkdtemp(prefix="crd-hang-"))
    program = (
        "import sys, time\n"
        "from contextros.cli.daemon import server\n"
        "from contextros.cli.daemon.place import daemon_place\n"
        "server.TEARDOWN_LIMIT = 3.0\n"
        "def hang(self):\n"
        "    time.sleep(600)\n"
        "server.DaemonServer._destroy_nodes = hang\n"
        "sys.exit(server.serve(daemon_place(), 0.5, None))\n"
    )
    try:
        env = dict(os.environ, CONTEXTROS_RUNTIME_DIR=str(runtime))
        done = subprocess.run(
            [sys.executable, "-c", program], capture_output=True, text=True, env=env, timeout=60
        )
        assert done.returncode == 1, done.stdout + done.stderr
        assert "stopping" in done.stdout
        assert "Timeout (0:00:03)!" in done.stderr and "in hang" in done.stderr, done.stderr
    finally:
        shutil.rmtree(runtime, ignore_errors=True)
