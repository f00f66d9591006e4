"""spin_nodes' way out, in processes of their own: what must be closed is closed before the
nodes are torn down, and a program's main can bound that teardown (a Fast DDS deadlock
deleting a participant holds the GIL; only faulthandler's C thread ends the process)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

PROGRAM = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from rclpy.node import Node
    from contextros.ros import spin_nodes

    class Stuck(Node):
        def destroy_node(self):
            if HANG:
                time.sleep(600)
            return super().destroy_node()

    rclpy.init()
    spin_nodes(
        [Stuck("spinning_test")],
        timeout=0.2,
        before_teardown=lambda: print("closed", flush=True),
        teardown_limit=2.0,
    )
    print("torn down", flush=True)
    time.sleep(3.0)  # longer than the limit: the watchdog was called off
    print("went on", flush=True)
    rclpy.try_shutdown()
    """
)


def run(hang: bool) -> subprocess.CompletedProcess[str]:
    program = PROGRAM.replace("HANG", str(hang))
    return subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=60
    )


def test_a_teardown_that_hangs_ends_the_process_with_the_stack_it_hung_in() -> None:
    done = run(hang=True)
    assert done.returncode == 1, done.stdout + done.stderr
    assert done.stdout.split() == ["closed"], "closed first, and never torn down"
    assert "Timeout (0:00:02)!" in done.stderr and "in destroy_node" in done.stderr


def test_a_teardown_in_time_calls_the_watchdog_off() -> None:
    done = run(hang=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["closed", "torn down", "went on"]
