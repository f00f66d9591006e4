"""Running context nodes: one executor for several nodes, clean exits on signals.

Several participants can share one process and one executor (they share the process's
decisive configuration too, as they must: it is one process).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node

RCLError = rclpy_implementation.RCLError


def spin_nodes(
    nodes: Sequence[Node],
    *,
    until: Callable[[], bool] | None = None,
    timeout: float | None = None,
) -> None:
    """Spin `nodes` in one single-threaded executor until shutdown, `until()` or `timeout`.

    SIGINT and SIGTERM end the spin quietly (rclpy reports them as KeyboardInterrupt or
    ExternalShutdownException); nodes are destroyed on the way out, so context nodes say
    goodbye to the manager when they still can.
    """
    executor = SingleThreadedExecutor()
    for node in nodes:
        executor.add_node(node)
    deadline = None if timeout is None else time.monotonic() + timeout
    try:
        while rclpy.ok():
            if until is not None and until():
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        # A signal shut the context down between two spins: same as above.
        if rclpy.ok():
            raise
    finally:
        for node in nodes:
            with contextlib.suppress(Exception):
                node.destroy_node()
        executor.shutdown(timeout_sec=0.5)
