"""The daemon's local protocol: one JSON request per connection, one JSON answer.

A request names a `command` ("activate", "status", "ping" or "stop") with the command
line's options; the answer's `outcome` says what the command line does with it:

| outcome | carries | the command line |
|---|---|---|
| `result` | the manager's answer to an activation | prints it, exits 0 or 1 |
| `registry` | the manager's registry as `registry_to_dict` gives it | prints it |
| `no_manager` | `message` | exits 3, as without the daemon |
| `failed` | `message` (the command was refused before it was sent) | exits 1 |
| `busy`, `refused` | `message` | asks the manager itself |
| `pong`, `stopping` | `pid` | (`contextros daemon status/stop`) |

The socket is private to its user, and the daemon still checks every request as input
from outside: its size, every field's type and range.
"""

from __future__ import annotations

import json
import math
import socket
import time
from typing import Any

from contextros.cli.ros_arguments import namespace_problem

PROTOCOL = 1
MAX_REQUEST = 64 * 1024
MAX_NAMES = 256
MAX_NAME = 256
MAX_TEXT = 4096
MAX_SECONDS = 24 * 3600.0
COMMANDS = ("activate", "status", "ping", "stop")


class WireError(Exception):
    """A message that is not one JSON object on one line, or too long."""


def send(connection: socket.socket, message: dict[str, Any]) -> None:
    connection.sendall(json.dumps(message, separators=(",", ":")).encode() + b"\n")


def receive(
    connection: socket.socket, limit: int | None = None, within: float | None = None
) -> dict[str, Any]:
    """Read one message; WireError if the peer closes first, sends more than `limit`
    bytes, takes longer than `within` seconds in all, or sends anything but a JSON object."""
    deadline = None if within is None else time.monotonic() + within
    chunks: list[bytes] = []
    size = 0
    while True:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise WireError(f"no whole message within {within:g} s")
            connection.settimeout(left)
        try:
            chunk = connection.recv(65536)
        except TimeoutError as error:
            raise WireError(f"no whole message within {within or 0:g} s") from error
        if not chunk:
            raise WireError("the connection closed before a whole message")
        newline = chunk.find(b"\n")
        size += len(chunk) if newline < 0 else newline
        if limit is not None and size > limit:
            raise WireError(f"a message over {limit} bytes")
        if newline >= 0:
            chunks.append(chunk[:newline])
            break
        chunks.append(chunk)
    try:
        message = json.loads(b"".join(chunks))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise WireError(f"not JSON: {error}") from error
    if not isinstance(message, dict):
        raise WireError("not a JSON object")
    return message


def _names(value: Any, field: str) -> str | None:
    if not isinstance(value, list) or len(value) > MAX_NAMES:
        return f"{field} must be a list of at most {MAX_NAMES} names"
    if not all(isinstance(name, str) and len(name) <= MAX_NAME for name in value):
        return f"{field} must hold strings of at most {MAX_NAME} characters"
    return None


def _seconds(value: Any, field: str) -> str | None:
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not number or not math.isfinite(value) or not 0 <= value <= MAX_SECONDS:
        return f"{field} must be a number of seconds from 0 to {MAX_SECONDS:g}"
    return None


def _text(value: Any, field: str, limit: int = MAX_TEXT) -> str | None:
    if not isinstance(value, str) or len(value) > limit:
        return f"{field} must be a string of at most {limit} characters"
    return None


def request_problem(request: dict[str, Any]) -> str | None:
    """What is wrong with `request` (the first thing found), or None."""
    if request.get("protocol") != PROTOCOL:
        return f"protocol must be {PROTOCOL}"
    command = request.get("command")
    if command not in COMMANDS:
        return f"command must be one of {', '.join(COMMANDS)}"
    if command in ("ping", "stop"):
        return None
    if "namespace" not in request:
        return "namespace is missing (null for the command line's default)"
    namespace = request["namespace"]
    if namespace is not None and (
        not isinstance(namespace, str) or len(namespace) > MAX_NAME or namespace_problem(namespace)
    ):
        return "namespace must be null or a ROS namespace"
    if problem := _seconds(request.get("wait_manager"), "wait_manager"):
        return problem
    if command == "status":
        return None
    for field in ("on", "off", "expect"):
        if problem := _names(request.get(field), field):
            return problem
    for field in ("sync", "atomic"):
        if not isinstance(request.get(field), bool):
            return f"{field} must be true or false"
    if problem := _seconds(request.get("timeout"), "timeout"):
        return problem
    count = request.get("expect_count")
    if not isinstance(count, int) or isinstance(count, bool) or not 0 <= count <= 1_000_000:
        return "expect_count must be an integer from 0 to 1000000"
    return _text(request.get("reason"), "reason") or _text(
        request.get("requester"), "requester", MAX_NAME
    )


def result_as_dict(result: Any) -> dict[str, Any]:
    """An ActivationResult as the JSON the command line prints."""
    return {
        name: list(value) if isinstance(value, tuple) else value
        for name, value in vars(result).items()
    }
