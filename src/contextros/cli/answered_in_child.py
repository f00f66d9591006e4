"""A command that asks the manager itself does so from a forked child process.

The child makes the ROS node, asks, sends its answer back over a pipe, and only then
tears the node down. The command prints the answer and exits with its status whatever
that teardown does. Under discovery churn Fast DDS 3.2 can deadlock deleting a
participant: `DomainParticipant::set_listener` spins until a discovery callback ends,
and that callback waits for a mutex the deletion holds. rclpy holds the GIL all along,
so no Python thread or signal handler can end such a process. It can crash there too.

A child that is not gone `TEARDOWN_LIMIT` seconds after answering is killed, and so is
a child whose command was killed. A killed participant announces no departure: its
peers drop it when its lease ends. Its shared-memory segments are removed by the
watchdog of Fast DDS's other processes on the host, or by `fastdds shm clean`.

Without `os.fork`, or in a process that already runs threads or rclpy (a fork would
copy their state without their threads), the command asks in-process as before.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import json
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from typing import Any, NoReturn

TEARDOWN_LIMIT = 3.0  # seconds a child may take to tear its node down after answering
INTERRUPTED = 130  # the shell's status for a command ended by Ctrl-C
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a process gets when its parent dies

# The work: given the stack its ROS teardown goes on, the command's answer (a JSON-able
# dict with an "outcome"); the stack is closed once the answer is on its way.
Work = Callable[[ExitStack], dict[str, Any]]


@contextmanager
def answered_in_child(
    work: Work, unanswered: str, limit: float = TEARDOWN_LIMIT
) -> Iterator[dict[str, Any]]:
    """The answer `work` gives, computed in a child process that is reaped when the block
    ends, after the caller printed the answer (killed if still there `limit` s later).
    `unanswered` says what a child that ended without an answer means for the user."""
    if not _can_fork():
        with ExitStack() as teardown:
            yield work(teardown)
        return
    readable, writable = os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    child = os.fork()
    if child == 0:  # pragma: no cover - runs in the child, which never returns
        os.close(readable)
        _answer_and_exit(work, writable, parent)
    os.close(writable)
    interrupted = {"outcome": "interrupted", "message": f"interrupted; {unanswered}"}
    try:
        with os.fdopen(readable, "rb") as pipe:
            data = pipe.read()  # until the child sent its report, or ended without one
    except KeyboardInterrupt:  # the child got the same Ctrl-C, or gets it now (a SIGTERM)
        with contextlib.suppress(OSError):
            os.kill(child, signal.SIGINT)
        _reap(child, limit)
        yield interrupted
        return
    try:
        report = json.loads(data) if data else {}
    except ValueError:  # cut short: the child died while writing it
        report = {}
    if "answer" in report:
        try:
            yield report["answer"]
        finally:
            sys.stdout.flush()  # the answer is out before the child's teardown ends
            _reap(child, limit)
        return
    ended = _describe(_reap(child, limit))
    if report.get("interrupted"):
        yield interrupted
    elif "error" in report:
        yield {
            "outcome": "failed",
            "message": f"the command's ROS client (pid {child}) failed: {report['error']} "
            f"(traceback above); {unanswered}",
        }
    else:
        yield {
            "outcome": "failed",
            "message": f"the command's ROS client (pid {child}) {ended} without an answer; "
            f"{unanswered}",
        }


def _can_fork() -> bool:
    return hasattr(os, "fork") and threading.active_count() == 1 and "rclpy" not in sys.modules


def _answer_and_exit(work: Work, writable: int, parent: int) -> NoReturn:  # pragma: no cover
    """The child's whole life. Its report goes to the parent, closing the pipe, before its
    ROS node is torn down: {"answer": ...}, {"interrupted": true} or {"error": "..."}."""
    status = 1
    try:
        _die_with(parent)
        with contextlib.suppress(OSError):
            os.dup2(2, 1)  # the command's standard output is the parent's alone
        faulthandler.enable()  # a crash before the report shows where it happened
        with ExitStack() as teardown:
            try:
                report = json.dumps({"answer": work(teardown)})
                status = 0
            except BaseException as error:  # judged before teardown shuts rclpy down
                if _interrupted(error):
                    report, status = json.dumps({"interrupted": True}), INTERRUPTED
                else:
                    traceback.print_exc()
                    report = json.dumps({"error": f"{type(error).__name__}: {error}"})
            faulthandler.disable()  # one in teardown is the middleware's, after the report
            view = memoryview(report.encode())
            while view:
                view = view[os.write(writable, view) :]
            os.close(writable)  # the parent stops waiting, whatever teardown does
    except BaseException:  # teardown's, once the parent has the report
        pass
    finally:
        with contextlib.suppress(BaseException):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(status)


def _die_with(parent: int) -> None:  # pragma: no cover - child only
    """Be killed when the command's process dies (Linux); exit now if it already has."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:
        os._exit(1)


def _interrupted(error: BaseException) -> bool:  # pragma: no cover - child only
    """Ctrl-C: Python's KeyboardInterrupt, or rclpy's own handler, which shuts the context
    down under the node (its calls then raise RCLError)."""
    rclpy = sys.modules.get("rclpy")
    return isinstance(error, KeyboardInterrupt) or (rclpy is not None and not rclpy.ok())


def _reap(child: int, limit: float | None) -> int | None:
    """The child's wait status once it ended (killed if still there after `limit` s), or
    None if it cannot be read (SIGCHLD ignored)."""
    deadline = None if limit is None else time.monotonic() + limit
    while True:
        try:
            done, status = os.waitpid(child, 0 if deadline is None else os.WNOHANG)
            if done:
                return status
            assert deadline is not None
            if time.monotonic() < deadline:
                time.sleep(0.005)
                continue
            os.kill(child, signal.SIGKILL)
            deadline = None
        except ChildProcessError:
            return None
        except KeyboardInterrupt:  # Ctrl-C while waiting: stop waiting
            deadline = time.monotonic()


def _describe(status: int | None) -> str:
    if status is None:
        return "ended"
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        try:
            name = signal.Signals(number).name
        except ValueError:
            name = f"signal {number}"
        return f"was killed by {name}"
    return f"exited with status {os.waitstatus_to_exitcode(status)}"
