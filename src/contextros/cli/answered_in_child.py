"""A command that asks the manager itself does so from a forked child process.

The child makes the ROS node, asks, sends its answer back over a pipe, and only then
tears the node down. The command prints the answer and exits with its status whatever
that teardown does: under discovery churn, Fast DDS 3.2 can deadlock deleting a
participant (`DomainParticipant::set_listener` waits, holding the GIL, on a discovery
callback that waits for it) or crash there. A child that is not gone
`TEARDOWN_LIMIT` seconds after answering is killed; Fast DDS's other processes reclaim
its shared-memory segments.

Without `os.fork`, or in a process that already runs threads or rclpy (a fork would
copy their state without their threads), the command asks in-process as before.
"""

from __future__ import annotations

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
from typing import Any

TEARDOWN_LIMIT = 3.0  # seconds a child may take to tear its node down after answering
INTERRUPTED = 130  # the shell's status for a command ended by Ctrl-C

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
    child = os.fork()
    if child == 0:  # pragma: no cover - runs in the child, which never returns
        os.close(readable)
        _answer_and_exit(work, writable)
    os.close(writable)
    try:
        with os.fdopen(readable, "rb") as pipe:
            data = pipe.read()  # until the child sent its answer, or ended without one
    except KeyboardInterrupt:  # the child got the same Ctrl-C
        _reap(child, limit)
        yield {"outcome": "interrupted", "message": f"interrupted; {unanswered}"}
        return
    if data:
        try:
            yield json.loads(data)
        finally:
            _reap(child, limit)
        return
    status = _reap(child, None)
    if os.WIFEXITED(status) and os.WEXITSTATUS(status) == INTERRUPTED:
        yield {"outcome": "interrupted", "message": f"interrupted; {unanswered}"}
        return
    yield {
        "outcome": "failed",
        "message": f"the command's ROS client (pid {child}) {_describe(status)} without an "
        f"answer; {unanswered}",
    }


def _can_fork() -> bool:
    return hasattr(os, "fork") and threading.active_count() == 1 and "rclpy" not in sys.modules


def _answer_and_exit(work: Work, writable: int) -> None:  # pragma: no cover - child only
    status, answered = 0, False
    try:
        faulthandler.enable()  # a crash before the answer shows where it happened
        with ExitStack() as teardown:
            answer = json.dumps(work(teardown)).encode()
            faulthandler.disable()  # one in teardown is the middleware's, after the answer
            view = memoryview(answer)
            while view:
                view = view[os.write(writable, view) :]
            os.close(writable)
            answered = True
    except BaseException as error:
        status = INTERRUPTED if _interrupted(error) else 1
        if status != INTERRUPTED and not answered:  # after the answer: teardown's, unseen
            traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


def _interrupted(error: BaseException) -> bool:  # pragma: no cover - child only
    """Ctrl-C: Python's KeyboardInterrupt, or rclpy's own handler, which shuts the context
    down under the node (its calls then raise RCLError)."""
    rclpy = sys.modules.get("rclpy")
    return isinstance(error, KeyboardInterrupt) or (rclpy is not None and not rclpy.ok())


def _reap(child: int, limit: float | None) -> int:
    """The child's wait status, once it ended: killed if still there after `limit` s."""
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
            return 0
        except KeyboardInterrupt:  # a second Ctrl-C: stop waiting
            deadline = time.monotonic()


def _describe(status: int) -> str:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        try:
            name = signal.Signals(number).name
        except ValueError:
            name = f"signal {number}"
        return f"was killed by {name}"
    return f"exited with status {os.waitstatus_to_exitcode(status)}"
