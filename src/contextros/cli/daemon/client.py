"""The command line's side of the daemon: ask it, or start it for the next command.

Nothing here imports rclpy: a command answered by the daemon costs an interpreter start,
the CLI's own imports and one local round trip.
"""

from __future__ import annotations

import fcntl
import os
import socket
import sys
import time
from importlib.util import find_spec
from typing import Any

from contextros.cli.daemon.place import DaemonPlace, PlaceError, daemon_place
from contextros.cli.daemon.wire import PROTOCOL, WireError, receive, send

DISABLE_VARIABLE = "CONTEXTROS_NO_DAEMON"
START_WAIT = 15.0


class DaemonLost(Exception):
    """The daemon took the request but gave no answer."""


def wanted(environ: dict[str, str] | os._Environ[str] = os.environ) -> bool:
    return environ.get(DISABLE_VARIABLE, "").lower() not in ("1", "true", "yes", "on")


def ask(place: DaemonPlace, request: dict[str, Any], timeout: float) -> dict[str, Any] | None:
    """The daemon's answer to `request`, or None when no daemon listens at `place`."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as connection:
        try:
            connection.connect(str(place.socket))
        except (FileNotFoundError, ConnectionRefusedError):
            return None
        try:
            connection.settimeout(timeout)
            send(connection, {"protocol": PROTOCOL, **request})
            return receive(connection)
        except (OSError, WireError) as error:
            raise DaemonLost(str(error) or type(error).__name__) from error


def starting(place: DaemonPlace) -> bool:
    """Whether a daemon holds the place's lock (it is starting, or serving)."""
    try:
        with open(place.lock, "a") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            return False
    except OSError:
        return False


def spawn(
    place: DaemonPlace, namespace: str | None = None, idle_timeout: float | None = None
) -> None:
    """Start a daemon in the background, detached from this command and its terminal."""
    import subprocess

    command = [sys.executable, "-m", "contextros", "daemon", "start", "--foreground"]
    if namespace:
        command += ["--warm-namespace", namespace]
    if idle_timeout is not None:
        command += ["--idle-timeout", repr(idle_timeout)]
    with open(place.log, "w") as log:
        subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            close_fds=True,
            start_new_session=True,
        )


def answer_for(request: dict[str, Any], timeout: float) -> dict[str, Any] | None:
    """What the daemon answers, or None: the command asks the manager itself (no daemon
    yet: one is started for the next command; or it is busy, or gave no answer)."""
    if not wanted():
        return None
    try:
        place = daemon_place()
    except PlaceError:
        return None
    try:
        answer = ask(place, request, timeout)
    except DaemonLost as error:
        print(
            f"contextros: the daemon gave no answer ({error}); asking the manager directly "
            f"(its log: {place.log})",
            file=sys.stderr,
        )
        return None
    if answer is None:
        if not starting(place) and find_spec("rclpy") is not None:
            spawn(place, request.get("namespace"))
        return None
    if answer.get("outcome") in ("busy", "refused"):
        return None
    return answer


def ping(place: DaemonPlace) -> dict[str, Any] | None:
    try:
        return ask(place, {"command": "ping"}, 5.0)
    except DaemonLost:
        return None


def start(
    place: DaemonPlace, namespace: str | None = None, idle_timeout: float | None = None
) -> dict[str, Any] | None:
    """Start the daemon unless it runs, and wait until it answers; its pong or None."""
    if pong := ping(place):
        return pong
    if not starting(place):
        spawn(place, namespace, idle_timeout)
    deadline = time.monotonic() + START_WAIT
    while time.monotonic() < deadline:
        if pong := ping(place):
            return pong
        time.sleep(0.05)
    return None


def stop(place: DaemonPlace) -> int | None:
    """Stop the daemon at `place` and wait until it has gone; its pid, or None if none ran."""
    try:
        answer = ask(place, {"command": "stop"}, 5.0)
    except DaemonLost:
        answer = None
    if answer is None:
        return None
    deadline = time.monotonic() + START_WAIT
    while starting(place) and time.monotonic() < deadline:
        time.sleep(0.05)
    pid: int = answer.get("pid", 0)
    return pid


__all__ = ["DaemonLost", "PlaceError", "answer_for", "daemon_place", "start", "stop", "wanted"]
