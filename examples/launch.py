"""A small launcher: ROS 2 nodes as child processes, their output as one timed stream.

pip installs of ROS 2 have no `ros2 launch`, so the demo, the tests and the benchmarks start
their processes with this. Every child runs with this interpreter (the ROS wheels' library
path is tied to it), localhost-only discovery, the given domain and no RMW override (the
wheels only carry Fast DDS; another RMW makes rcl exit with status 102).
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

REPOSITORY = Path(__file__).resolve().parent.parent
DEFAULT_DOMAIN_ID = 42


@dataclass(frozen=True)
class OutputLine:
    """One line a child printed, when (seconds since the launch started) and who printed it."""

    at: float
    process: str
    text: str


def ros_environment(domain_id: int | None = None) -> dict[str, str]:
    """The environment of a child: this one, isolated to the machine and one domain."""
    env = dict(os.environ)
    env.pop("RMW_IMPLEMENTATION", None)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if domain_id is None:
        domain_id = int(os.environ.get("ROS_DOMAIN_ID", DEFAULT_DOMAIN_ID))
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONPATH"] = os.pathsep.join(
        [str(REPOSITORY), *filter(None, [os.environ.get("PYTHONPATH")])]
    )
    return env


class Launch:
    """Starts processes, collects their output lines, and stops them all on exit.

    Use as a context manager: the children are interrupted (SIGINT, as Ctrl-C would), then
    killed if they do not exit within `grace` seconds, whatever ends the block.
    """

    def __init__(
        self,
        domain_id: int | None = None,
        *,
        grace: float = 3.0,
        extra_env: Mapping[str, str] | None = None,
    ) -> None:
        self.env = ros_environment(domain_id) | dict(extra_env or {})
        self.grace = grace
        self.started = time.monotonic()
        self.lines: queue.Queue[OutputLine] = queue.Queue()
        self.processes: dict[str, subprocess.Popen[str]] = {}
        self._readers: list[threading.Thread] = []

    def __enter__(self) -> Launch:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop_all()

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def start_module(self, name: str, module: str, *args: str) -> subprocess.Popen[str]:
        """Run `python -m module args...` as the child called `name`."""
        return self.start(name, [sys.executable, "-m", module, *args])

    def start(self, name: str, command: Sequence[str]) -> subprocess.Popen[str]:
        process = subprocess.Popen(
            list(command),
            cwd=REPOSITORY,
            env=self.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            encoding="utf-8",
            errors="replace",
            bufsize=1,
        )
        self.processes[name] = process
        reader = threading.Thread(target=self._read, args=(name, process), daemon=True)
        reader.start()
        self._readers.append(reader)
        return process

    def _read(self, name: str, process: subprocess.Popen[str]) -> None:
        assert process.stdout is not None  # started with stdout=PIPE
        for text in process.stdout:
            self.lines.put(OutputLine(self.elapsed(), name, text.rstrip("\n")))

    def next_line(self, timeout: float) -> OutputLine | None:
        """The next output line of any child, or None when none came within `timeout`."""
        try:
            return self.lines.get(timeout=max(0.0, timeout))
        except queue.Empty:
            return None

    def stop(self, name: str) -> int | None:
        """Interrupt one child, kill it after the grace period; return its exit status."""
        process = self.processes[name]
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(self.grace)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        return process.returncode

    def stop_all(self) -> None:
        # Interrupt all at once, so their grace periods overlap.
        for process in self.processes.values():
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.grace
        for process in self.processes.values():
            try:
                process.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for reader in self._readers:
            reader.join(timeout=1.0)
