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


IN_THREAD = textwrap.dedent(
    """
    import os, signal, threading, time
    import rclpy
    from rclpy.node import Node
    from contextros.cli import exits
    from contextros.ros.spinning import spinning_in_thread

    exits.stop_on_signals()  # as `contextros dashboard`: a stop signal raises
    rclpy.init()
    node = Node("spinning_in_thread_test")
    node.create_timer(0.01, lambda: time.sleep(0.5))  # the spinner is busy 0.5 s at a time
    try:
        with spinning_in_thread(node, "spinner"):
            time.sleep(0.1)
            threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGTERM)).start()
            raise BrokenPipeError  # the dashboard's URL line met a closed stdout
    except BaseException as error:
        alive = [t.name for t in threading.enumerate() if t.name == "spinner"]
        print(type(error).__name__, alive, flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    """
)


def test_a_signal_while_the_spinner_is_joined_does_not_leave_it_running() -> None:
    """`contextros dashboard` with a closed stdout, stopped while it tore down (issue: a
    rare `terminate called`, status -6): the signal's exception broke out of the spinner's
    join, and Python finalized with the thread still inside rclpy."""
    done = subprocess.run(
        [sys.executable, "-c", IN_THREAD], capture_output=True, text=True, timeout=60
    )
    assert done.stdout.split("\n")[0] == "BrokenPipeError []", done.stdout + done.stderr
    assert done.returncode == 0, done.stderr
