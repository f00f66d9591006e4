"""How a command ends when it is told to: SIGINT, SIGTERM, or a reader that went away.

`main` installs `stop_on_signals` first thing. Either signal then raises `Stopped`, a
KeyboardInterrupt, so every `except KeyboardInterrupt` on the way (spin_nodes, the
command's ROS client) treats SIGTERM as it treats Ctrl-C; rclpy's own handler, installed
later by `rclpy.init`, shuts its context down and then calls this one. `main` turns the
interruption into the status docs/cli.md gives: 128 + the signal's number (130, 143), or 0
for the commands that run until stopped. A closed standard output (`contextros status |
head -1`) ends the command quietly with 141, the status SIGPIPE gives in a shell.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sys
from types import FrameType
from typing import Any

CLOSED_OUTPUT = 128 + signal.SIGPIPE


class Stopped(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


# The last stop signal received, for the commands that report an interruption themselves.
received: int | None = None
# rclpy's own handler (it runs first, in C) shut the command's ROS context down under it:
# a signal, even if the error it caused left this module's handler no turn to run.
ros_context_shut_by_signal = False


Handlers = dict[int, Any]


def stop_on_signals() -> Handlers:
    """Install the handlers; the ones they replace."""
    global received, ros_context_shut_by_signal
    received, ros_context_shut_by_signal = None, False
    return {signum: signal.signal(signum, _stop) for signum in (signal.SIGINT, signal.SIGTERM)}


def after_command(previous: Handlers | None) -> None:
    """Put `previous` handlers back (main called by a program of its own), or, for the
    command's process (None), ignore the signals: its status is decided, and a signal
    while the interpreter finalizes would end it with another."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        handler = signal.SIG_IGN if previous is None else previous[signum]
        signal.signal(signum, handler if handler is not None else signal.SIG_DFL)


def _stop(signum: int, frame: FrameType | None) -> None:
    del frame
    global received
    received = signum
    raise Stopped(signum)


def stopped_under(error: BaseException) -> Stopped | None:
    """The stop signal behind `error`, if any. The signal's exception may surface as
    another: Python wraps one raised in a class body's `__set_name__` in a RuntimeError,
    and a teardown after rclpy's own handler shut its context down raises RCLError (with
    the interruption as its context)."""
    seen: set[int] = set()
    cause: BaseException | None = error
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, Stopped):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None


def interrupted_status() -> int:
    """The status of a command interrupted by the last stop signal (Ctrl-C if none)."""
    return 128 + (received or signal.SIGINT)


def output_closed() -> int:
    """After a BrokenPipeError on the standard output: its descriptor goes to /dev/null (so
    that Python's flush at exit raises nothing more); the command's status."""
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    return CLOSED_OUTPUT


def output_gone() -> bool:
    """Whether the standard output is a pipe whose reader went away: a command that prints
    only now and then (`contextros watch | head -3`) ends then, not at its next line."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), 0)  # POLLERR and POLLHUP are always reported
        return any(events & select.POLLERR for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return False
