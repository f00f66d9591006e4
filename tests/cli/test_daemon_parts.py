"""The daemon's pure parts: which environment reaches which daemon, the private directory,
and the checks on every request (no ROS here; tests/ros/test_cli_daemon.py runs it)."""

from __future__ import annotations

import os
import socket
import threading
from pathlib import Path
from typing import Any

import pytest

from contextros.cli.daemon import client
from contextros.cli.daemon.place import (
    PlaceError,
    daemon_place,
    environment_key,
    private_directory,
    runtime_directory,
)
from contextros.cli.daemon.wire import WireError, receive, request_problem, result_as_dict
from contextros.protocol import ActivationResult

BASE = {"ROS_DOMAIN_ID": "7", "HOME": "/home/me"}


def test_a_daemon_serves_one_ros_environment() -> None:
    key = environment_key(BASE)
    assert environment_key(dict(BASE)) == key
    assert environment_key(BASE | {"HOME": "/elsewhere", "TERM": "dumb"}) == key
    # The ROS wheels' bootstrapper rewrites LD_LIBRARY_PATH in each interpreter.
    assert environment_key(BASE | {"LD_LIBRARY_PATH": "/a:/b"}) == key
    for changed in (
        {"ROS_DOMAIN_ID": "8"},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"},
        {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"},
        {"FASTDDS_DEFAULT_PROFILES_FILE": "/p.xml"},
        {"ROS_STATIC_PEERS": "10.0.0.2"},
        {"PYTHONPATH": "/src"},
    ):
        assert environment_key(BASE | changed) != key, changed


def test_the_runtime_directory_is_chosen_in_order(tmp_path: Path) -> None:
    chosen = {"CONTEXTROS_RUNTIME_DIR": "/r", "XDG_RUNTIME_DIR": str(tmp_path)}
    assert runtime_directory(chosen) == Path("/r")
    assert runtime_directory({"XDG_RUNTIME_DIR": str(tmp_path)}) == tmp_path / "contextros"
    fallback = Path(f"/tmp/contextros-{os.getuid()}")
    assert runtime_directory({}) == fallback
    # Not this user's (kept by `sudo -E`), or missing: not used.
    assert runtime_directory({"XDG_RUNTIME_DIR": str(tmp_path / "missing")}) == fallback
    if os.getuid() == 0:  # only root can hand a directory to another user
        other = tmp_path / "other"
        other.mkdir()
        os.chown(other, 65534, 65534)
        assert runtime_directory({"XDG_RUNTIME_DIR": str(other)}) == fallback


def test_the_directory_must_be_private(tmp_path: Path) -> None:
    made = private_directory(tmp_path / "new")
    assert made.stat().st_mode & 0o777 == 0o700
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o755)
    shared.chmod(0o755)
    with pytest.raises(PlaceError, match=r"open to other users \(mode 755\)"):
        private_directory(shared)
    plain_file = tmp_path / "file"
    plain_file.write_text("")
    with pytest.raises(PlaceError, match=r"cannot create the daemon's directory .*file"):
        private_directory(plain_file)
    # A link, even to a private directory, could be redirected by whoever owns its parent.
    link = tmp_path / "link"
    link.symlink_to(made)
    with pytest.raises(PlaceError, match="link is not a directory"):
        private_directory(link)


def test_a_command_does_without_a_daemon_whose_directory_is_not_private(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    monkeypatch.setenv("CONTEXTROS_RUNTIME_DIR", str(shared))
    monkeypatch.delenv("CONTEXTROS_NO_DAEMON", raising=False)
    assert client.answer_for({"command": "status"}, 1.0) is None
    assert list(shared.iterdir()) == []  # nothing started, nothing written


def test_a_directory_too_deep_for_a_socket_is_refused_and_the_command_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    deep = tmp_path / ("d" * 100)
    monkeypatch.setenv("CONTEXTROS_RUNTIME_DIR", str(deep))
    monkeypatch.delenv("CONTEXTROS_NO_DAEMON", raising=False)
    with pytest.raises(PlaceError, match="too long a path for the daemon's socket"):
        daemon_place()
    assert client.answer_for({"command": "status"}, 1.0) is None
    assert not deep.exists()


def test_the_variable_turns_the_daemon_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CONTEXTROS_RUNTIME_DIR", str(tmp_path / "run"))
    for value in ("1", "true", "YES", "on"):
        assert not client.wanted({"CONTEXTROS_NO_DAEMON": value})
    assert client.wanted({"CONTEXTROS_NO_DAEMON": "0"}) and client.wanted({})
    monkeypatch.setenv("CONTEXTROS_NO_DAEMON", "1")
    assert client.answer_for({"command": "status"}, 1.0) is None
    assert not (tmp_path / "run").exists()


ACTIVATE = {
    "protocol": 1,
    "command": "activate",
    "namespace": "/robot1",
    "wait_manager": 5.0,
    "on": ["Indoor"],
    "off": [],
    "expect": [],
    "sync": True,
    "atomic": False,
    "timeout": 0.0,
    "expect_count": 0,
    "reason": "",
    "requester": "me@pid1",
}


def test_a_well_formed_request_passes() -> None:
    assert request_problem(ACTIVATE) is None
    assert request_problem({"protocol": 1, "command": "ping"}) is None
    status = {"protocol": 1, "command": "status", "namespace": None, "wait_manager": 0}
    assert request_problem(status) is None


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"protocol": 2}, "protocol"),
        ({"command": "shutdown"}, "command must be one of"),
        ({"namespace": "robot1"}, "namespace"),
        ({"namespace": 3}, "namespace"),
        ({"wait_manager": -1}, "wait_manager"),
        ({"wait_manager": float("nan")}, "wait_manager"),
        ({"wait_manager": True}, "wait_manager"),
        ({"wait_manager": "5"}, "wait_manager"),
        ({"on": "Indoor"}, "on must be a list"),
        ({"off": [1]}, "off must hold strings"),
        ({"expect": ["n"] * 257}, "expect must be a list of at most 256"),
        ({"on": ["x" * 257]}, "on must hold strings of at most 256"),
        ({"sync": 1}, "sync must be true or false"),
        ({"atomic": None}, "atomic"),
        ({"timeout": 1e9}, "timeout"),
        ({"expect_count": 1.5}, "expect_count"),
        ({"expect_count": -1}, "expect_count"),
        ({"expect_count": False}, "expect_count"),
        ({"reason": "r" * 5000}, "reason must be a string of at most 4096"),
        ({"requester": None}, "requester"),
    ],
)
def test_each_bad_field_is_named(change: dict[str, Any], named: str) -> None:
    problem = request_problem(ACTIVATE | change)
    assert problem is not None and named in problem, problem


def test_a_missing_field_is_named() -> None:
    for field in ("on", "sync", "timeout", "expect_count", "reason", "wait_manager", "namespace"):
        request = {k: v for k, v in ACTIVATE.items() if k != field}
        problem = request_problem(request)
        assert problem is not None and field in problem, (field, problem)


def _received(data: bytes, limit: int | None = None) -> dict[str, Any]:
    left, right = socket.socketpair()
    with left, right:
        sender = threading.Thread(target=lambda: (left.sendall(data), left.close()))
        sender.start()
        try:
            return receive(right, limit)
        finally:
            sender.join()


def test_receive_takes_one_json_object_within_its_limit() -> None:
    assert _received(b'{"a": 1}\n{"ignored": 2}\n') == {"a": 1}
    with pytest.raises(WireError, match="not a JSON object"):
        _received(b"[1]\n")
    with pytest.raises(WireError, match="not JSON"):
        _received(b"\xff\xfe\n")
    with pytest.raises(WireError, match="closed before a whole message"):
        _received(b'{"a": 1}')
    with pytest.raises(WireError, match="over 100 bytes"):
        _received(b"{" + b" " * 200_000 + b"}\n", limit=100)
    with pytest.raises(WireError, match="over 100 bytes"):  # in one chunk with its newline
        _received(b"{" + b" " * 150 + b"}\n", limit=100)
    left, right = socket.socketpair()
    with left, right:
        left.sendall(b'{"slow": ')  # and nothing more
        with pytest.raises(WireError, match=r"no whole message within 0.2 s"):
            receive(right, within=0.2)


def test_a_result_becomes_the_json_the_command_line_prints() -> None:
    result = ActivationResult(True, "ok", 4, ("Indoor",), ("/a",), (), 0.01)
    assert result_as_dict(result) == {
        "success": True,
        "message": "ok",
        "epoch": 4,
        "active": ["Indoor"],
        "acknowledged": ["/a"],
        "not_acknowledged": [],
        "elapsed": 0.01,
    }
