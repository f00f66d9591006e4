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
from pathlib import Path
from typing import Any

from contextros.cli.daemon.place import DaemonPlace, PlaceError, daemon_place
from contextros.cli.daemon.wire import PROTOCOL, WireError, receive, send

DISABLE_VARIABLE = "CONTEXTROS_NO_DAEMON"
START_WAIT = 15.0
STOP_WAIT = 20.0
CONNECT_TIMEOUT = 2.0
# Commands start a daemon at most this often (one that fails at start-up is not started
# again by every command).
SPAWN_PAUSE = 10.0


class DaemonUnreachable(Exception):
    """Nothing was sent: no daemon listens, or its socket cannot be reached."""

    def __init__(self, message: str, start_one: bool) -> None:
        super().__init__(message)
        self.start_one = start_one  # no daemon listens: one may be started


class DaemonLost(Exception):
    """The daemon took the whole request but gave no answer: what it did is unknown."""


def wanted(environ: dict[str, str] | os._Environ[str] = os.environ) -> bool:
    return environ.get(DISABLE_VARIABLE, "").lower() not in ("1", "true", "yes", "on")


def ask(place: DaemonPlace, request: dict[str, Any], timeout: float) -> dict[str, Any]:
    """The daemon's answer to `request`. DaemonUnreachable if it was not sent whole (the
    daemon then does nothing), DaemonLost if it was and no answer came."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as connection:
        connection.settimeout(CONNECT_TIMEOUT)
        try:
            connection.connect(str(place.socket))
        except (FileNotFoundError, ConnectionRefusedError) as error:
            raise DaemonUnreachable(str(error), start_one=True) from error
        except OSError as error:
            raise DaemonUnreachable(str(error), start_one=False) from error
        try:
            send(connection, {"protocol": PROTOCOL, **request})
        except OSError as error:  # a part of a request is no request (the daemon drops it)
            raise DaemonUnreachable(str(error), start_one=False) from error
        try:
            connection.settimeout(timeout)
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
) -> bool:
    """Start a daemon in the background, detached from this command and its terminal and
    writing to its log; whether it was started."""
    import subprocess

    command = [sys.executable, "-m", "contextros", "daemon", "start", "--foreground"]
    command += ["--expect-key", place.key]  # it serves only the environment asked for
    if namespace:
        command += ["--warm-namespace", namespace]
    if idle_timeout is not None:
        command += ["--idle-timeout", repr(idle_timeout)]
    try:
        with open(place.log, "a") as log:  # the daemon empties it once it holds the lock
            daemon = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                close_fds=True,
                start_new_session=True,
            )
        place.pid_file.write_text(str(daemon.pid))
    except OSError:
        return False
    return True


def _spawned_alive(place: DaemonPlace) -> bool:
    """Whether the daemon last started here is still alive (it may not hold the lock yet;
    just after the fork its command line is still its parent's)."""
    try:
        pid = int(place.pid_file.read_text())
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state in ("Z", "X"):  # exited (a zombie until the command that started it exits)
            return False
        if _started_lately(place):
            return True
        command = Path(f"/proc/{pid}/cmdline").read_bytes()  # not a reused pid
    except (OSError, ValueError, IndexError):
        return False
    return b"daemon\0start" in command and place.key.encode() in command


def _started_lately(place: DaemonPlace) -> bool:
    """Whether a command started a daemon here less than SPAWN_PAUSE ago."""
    try:
        return time.time() - place.pid_file.stat().st_mtime < SPAWN_PAUSE
    except OSError:
        return False


def answer_for(request: dict[str, Any], timeout: float) -> dict[str, Any] | None:
    """What the daemon answers, or None: the command asks the manager itself (no daemon
    yet: one is started for the next command; or it is busy, or unreachable).

    A daemon that took an activation and gave no answer is not asked again, nor is the
    manager: the command may have been carried out, or may still be. The answer is then a
    failure that says so; a status, which changes nothing, is asked of the manager."""
    if not wanted():
        return None
    try:
        place = daemon_place()
    except PlaceError:
        return None
    try:
        answer = ask(place, request, timeout)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM (contextros.cli.exits) while it answers
        unknown = (
            "nothing was changed"
            if request["command"] == "status"
            else ("whether it was carried out is unknown; see `contextros status`")
        )
        return {"outcome": "interrupted", "message": f"interrupted; {unknown}"}
    except DaemonUnreachable as error:
        startable = error.start_one and find_spec("rclpy") is not None
        if startable and not starting(place) and not _started_lately(place):
            spawn(place, request.get("namespace"))
        return None
    except DaemonLost as error:
        lost = f"the daemon took the command and gave no answer ({error}; its log: {place.log})"
        if request["command"] == "status":
            print(f"contextros: {lost}; asking the manager directly", file=sys.stderr)
            return None
        return {
            "outcome": "failed",
            "message": f"{lost}: whether it was carried out is unknown; see `contextros "
            "status`, and `--no-daemon` to do without the daemon",
        }
    if answer.get("outcome") in ("busy", "refused"):
        return None
    return answer


def ping(place: DaemonPlace) -> dict[str, Any] | None:
    try:
        return ask(place, {"command": "ping"}, 5.0)
    except (DaemonUnreachable, DaemonLost):
        return None


def start(
    place: DaemonPlace, namespace: str | None = None, idle_timeout: float | None = None
) -> dict[str, Any] | None:
    """Start the daemon unless it runs, and wait until it answers; its pong or None."""
    if pong := ping(place):
        return pong
    if not starting(place):
        spawn(place, namespace, idle_timeout)
    return _wait_for_pong(place, START_WAIT)


def _wait_for_pong(place: DaemonPlace, seconds: float) -> dict[str, Any] | None:
    """The daemon's pong once it listens; None after `seconds`, or once no daemon is
    starting any more (one that gave up: another environment's, or ROS missing)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if pong := ping(place):
            return pong
        if not starting(place) and not _spawned_alive(place):
            return None
        time.sleep(0.05)
    return None


def stop(place: DaemonPlace) -> tuple[int, bool] | None:
    """Stop the daemon at `place` (one still starting too) and wait until it has gone:
    (its pid, whether it went within STOP_WAIT), or None if none runs."""
    if not starting(place) and not _spawned_alive(place):
        return None
    # Running or starting: wait until it listens (a starting one would serve for its whole
    # idle timeout otherwise).
    if _wait_for_pong(place, START_WAIT) is None:
        return None
    try:
        answer = ask(place, {"command": "stop"}, 5.0)
    except (DaemonUnreachable, DaemonLost):
        return None
    deadline = time.monotonic() + STOP_WAIT
    while starting(place) and time.monotonic() < deadline:
        time.sleep(0.05)
    pid: int = answer.get("pid", 0)
    return pid, not starting(place)


__all__ = [
    "DaemonLost",
    "DaemonUnreachable",
    "PlaceError",
    "answer_for",
    "daemon_place",
    "start",
    "stop",
    "wanted",
]
