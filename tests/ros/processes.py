"""Child processes for the ROS tests: started with this interpreter, read line by line,
killed for sure at the end of the test that started them."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
PARTICIPANT_SCRIPT = HERE / "participant_process.py"
CLIENT_SCRIPT = HERE / "client_process.py"
# The C++ twin of participant_process.py (cpp/ros/tests/participant_process.cpp), as
# `make cpp` builds it.
CPP_PARTICIPANT = HERE.parent.parent / "build/cpp/ros/contextros_test_participant"


_held_domains: list[Any] = []  # open lock files, held for the life of this process


def reserve_domain_id(first: int, last: int = 229) -> int:
    """The first ROS domain id from `first` that no other process on this machine holds
    (an exclusive lock on a file per id, released when the process exits)."""
    import fcntl

    for domain in [*range(first, last + 1), *range(1, first)]:
        lock = open(f"/tmp/contextros-test-domain-{domain}.lock", "w")  # noqa: SIM115
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _held_domains.append(lock)
        return domain
    raise RuntimeError("no free ROS domain id for the tests")


class Child:
    """One process whose stdout lines are collected (JSON lines parsed) as they arrive."""

    def __init__(
        self,
        name: str,
        argv: Sequence[str],
        prefix: Sequence[str] = (),
        env: dict[str, str | None] | None = None,
        *,
        program: str = sys.executable,
    ) -> None:
        """Run `prefix... program argv...` (by default this interpreter, so that the ROS
        wheels' library path is this venv's), with `env` changing the environment."""
        self.name = name
        self.lines: list[str] = []
        self.events: list[dict[str, Any]] = []
        self._changed = threading.Condition()
        environment = dict(os.environ)
        environment.pop("RMW_IMPLEMENTATION", None)
        for key, value in (env or {}).items():
            if value is None:
                environment.pop(key, None)
            else:
                environment[key] = value
        self.popen = subprocess.Popen(
            [*prefix, program, *argv],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=environment,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                if line.startswith("{"):
                    with contextlib.suppress(json.JSONDecodeError):
                        self.events.append(json.loads(line))
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    def wait_for(
        self, predicate: Callable[[list[dict[str, Any]]], Any], timeout: float, what: str = ""
    ) -> Any:
        """Wait until `predicate(events)` is truthy and return it; fail with the output."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                value = predicate(self.events)
                if value:
                    return value
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (
                    self.popen.poll() is not None and not self._reader.is_alive()
                ):
                    output = "\n".join(self.lines[-30:])
                    raise AssertionError(
                        f"{self.name}: timed out waiting for {what or predicate} "
                        f"(exit status {self.popen.poll()}); last output:\n{output}"
                    )
                self._changed.wait(min(remaining, 0.2))

    def applied(self) -> list[dict[str, Any]]:
        with self._changed:
            return [e for e in self.events if e["event"] == "applied"]

    def wait_applied(self, epoch: int, timeout: float = 5.0) -> dict[str, Any]:
        return self.wait_for(
            lambda events: next(
                (e for e in events if e["event"] == "applied" and e["epoch"] >= epoch), None
            ),
            timeout,
            f"epoch {epoch} applied",
        )

    def send(self, line: str) -> None:
        assert self.popen.stdin is not None
        self.popen.stdin.write(line + "\n")
        self.popen.stdin.flush()

    def signal(self, signum: int) -> None:
        if self.popen.poll() is None:
            self.popen.send_signal(signum)

    def wait_exit(self, timeout: float = 10.0) -> int:
        status = self.popen.wait(timeout)
        self._reader.join(timeout)
        return status

    def output(self) -> str:
        return "\n".join(self.lines)


class ProcessGroup:
    def __init__(
        self, prefix: Sequence[str] = (), env: dict[str, str | None] | None = None
    ) -> None:
        self.children: list[Child] = []
        # Every child runs behind this prefix (e.g. `ip netns exec NS`) with these changes
        # to the environment (None removes a variable).
        self.prefix = tuple(prefix)
        self.env = env

    def start(self, name: str, argv: Sequence[str]) -> Child:
        child = Child(name, argv, self.prefix, self.env)
        self.children.append(child)
        return child

    def participant(self, name: str, *extra: str) -> Child:
        return self.start(name, [str(PARTICIPANT_SCRIPT), "--name", name, *extra])

    def cpp_participant(self, name: str, *extra: str) -> Child:
        """The C++ participant process (same layers, options and output as the Python one)."""
        if not CPP_PARTICIPANT.exists():
            raise AssertionError(f"{CPP_PARTICIPANT} is not built: run `make cpp`")
        child = Child(name, ["--name", name, *extra], program=str(CPP_PARTICIPANT))
        self.children.append(child)
        return child

    def manager(self, *extra: str, name: str = "manager") -> Child:
        return self.start(name, ["-m", "contextros", "manager", *extra])

    def kill_all(self) -> None:
        for child in self.children:
            if child.popen.poll() is None:
                child.popen.send_signal(signal.SIGKILL)
        for child in self.children:
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.popen.wait(5)
            for stream in (child.popen.stdin, child.popen.stdout):
                if stream is not None:
                    with contextlib.suppress(OSError):
                        stream.close()
