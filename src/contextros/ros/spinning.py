"""Running context nodes: one executor for several nodes, clean exits on signals.

Several participants can share one process and one executor (they share the process's
decisive configuration too, as they must: it is one process).
"""

from __future__ import annotations

import contextlib
import faulthandler
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from types import FrameType
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node

from contextros.ros.wait_loop import UnsupportedEntityError, WaitLoop

RCLError = rclpy_implementation.RCLError


def spin_nodes(
    nodes: Sequence[Node],
    *,
    until: Callable[[], bool] | None = None,
    timeout: float | None = None,
    lean: bool | None = None,
    before_teardown: Callable[[], None] | None = None,
    teardown_limit: float | None = None,
) -> None:
    """Spin `nodes` in one single-threaded executor until shutdown, `until()` or `timeout`.

    SIGINT and SIGTERM end the spin quietly, and the nodes are destroyed on the way out
    while ROS still works, so context nodes tell the manager they leave (it drops them at
    once instead of after the liveness timeout). To that end, when called in the main
    thread, the signals are caught here for the duration of the spin, before rclpy's
    handler would shut the context down.

    The executor (docs/protocol.md "Spinning lean"): by default (`lean=None`) `WaitLoop`,
    which serves a node's subscriptions, timers, services, clients, guard conditions and
    QoS events at half the CPU of rclpy's executor, as long as it can serve every entity of
    the nodes; once a node has one it cannot (a coroutine callback, an action), the spin
    goes on with rclpy's `SingleThreadedExecutor`, and says why in one log line.
    `lean=True`: `WaitLoop` or `UnsupportedEntityError`; `lean=False`: rclpy's executor
    (for callbacks that use `node.executor`, which `WaitLoop` does not set).

    `before_teardown` runs once the spin ended, before the nodes are destroyed (to close
    what must be closed, whatever the teardown does). `teardown_limit`, for a program's
    main: see `bounded_teardown`.
    """
    executor = WaitLoop(nodes) if lean is not False else _rclpy_executor(nodes)
    deadline = None if timeout is None else time.monotonic() + timeout
    _signalled.clear()
    previous = _catch_signals()
    try:
        while rclpy.ok():
            if until is not None and until():
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            try:
                executor.spin_once(timeout_sec=0.1)
            except UnsupportedEntityError as unsupported:
                # Raised before waiting (nothing taken yet): rclpy's executor takes over.
                if lean or not isinstance(executor, WaitLoop):
                    raise
                executor.shutdown()
                executor = _rclpy_executor(nodes)
                nodes[0].get_logger().info(f"spinning with rclpy's executor: {unsupported.reason}")
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A signal shut the context down between two spins (RCLError), or interrupted a take:
        # pybind11 turns the KeyboardInterrupt into a RuntimeError ("Unable to convert call
        # argument") or a SystemError ("returned a result with an exception set"). As above.
        if rclpy.ok() and not _signalled.is_set():
            raise
    finally:
        try:
            if before_teardown is not None:
                before_teardown()
        finally:
            with bounded_teardown(teardown_limit):
                # Last created first: nodes hosted by a shared participant leave before its
                # carrier, so the participant is never handed over on the way out.
                for node in reversed(nodes):
                    with contextlib.suppress(Exception):
                        node.destroy_node()
                executor.shutdown(timeout_sec=0.5)
            _restore_signals(previous)


def _rclpy_executor(nodes: Sequence[Node]) -> SingleThreadedExecutor:
    executor = SingleThreadedExecutor()
    for node in nodes:
        executor.add_node(node)
    return executor


@contextlib.contextmanager
def spinning_in_thread(
    node: Node, name: str, teardown_limit: float | None = None
) -> Iterator[None]:
    """Spin `node` in a thread of its own while the block runs (the main thread serving
    something else: the dashboard's web server). The thread has ended when the block has:
    a thread still inside rclpy when the interpreter finalizes aborts the process
    (`terminate called without an active exception`). `teardown_limit`: see
    `bounded_teardown`."""
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()

    ended = threading.Event()  # (an interrupted Thread.join may return early after it)

    def spin() -> None:
        try:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
        except (ExternalShutdownException, RCLError):
            if rclpy.ok():  # not a signal's shutdown: show it
                raise
        finally:
            ended.set()

    spinner = threading.Thread(target=spin, name=name, daemon=True)
    spinner.start()
    try:
        yield
    finally:
        stop.set()
        with bounded_teardown(teardown_limit):
            interrupted = _wait_despite_signals(ended)
            spinner.join()
            executor.shutdown(timeout_sec=0.5)
        if interrupted is not None and sys.exc_info()[1] is None:
            raise interrupted  # (else the exception under way stands)


def _wait_despite_signals(event: threading.Event) -> BaseException | None:
    """Wait for `event` even through a stop signal's exception (a handler raising while
    the main thread waits): the first such exception, once it is set."""
    interrupted = None
    while True:
        try:
            event.wait()
            return interrupted
        except BaseException as error:  # kept, raised once the event is set
            interrupted = interrupted or error


@contextlib.contextmanager
def bounded_teardown(limit: float | None) -> Iterator[None]:
    """For a program's main: if the block (tearing nodes down) takes more than `limit`
    seconds, the process ends with status 1 and every thread's stack on stderr. Under
    discovery churn Fast DDS 3.2 can deadlock deleting a participant while rclpy holds the
    GIL, where no Python code (a signal handler included) runs again; faulthandler's
    watchdog is a C thread. None: no limit (a library must not end its user's process)."""
    if limit is None:
        yield
        return
    faulthandler.dump_traceback_later(limit, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


_Handlers = dict[signal.Signals, Any]


# Set by a signal while spinning: its KeyboardInterrupt, raised inside a pybind11 call,
# may come out as another exception (see spin_nodes).
_signalled = threading.Event()


def _interrupt(signum: int, frame: FrameType | None) -> None:
    del signum, frame
    _signalled.set()
    raise KeyboardInterrupt


def _catch_signals() -> _Handlers:
    if threading.current_thread() is not threading.main_thread():
        return {}
    previous: _Handlers = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        previous[signum] = signal.signal(signum, _interrupt)
    return previous


def _restore_signals(previous: _Handlers) -> None:
    for signum, handler in previous.items():
        # None: a handler installed outside Python (rclpy's); SIG_DFL then, as ours is gone.
        signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
