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


LEAN_BY_DEFAULT = textwrap.dedent(
    """
    import sys
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import String
    from contextros.ros import spin_nodes

    LEAN = {lean}
    rclpy.init()
    node = Node("spinning_lean_test")
    seen = []

    def tick():
        # WaitLoop sets no node.executor; rclpy's executor does.
        seen.append("lean" if node.executor is None else "rclpy")
        if len(seen) == 3:  # a coroutine callback arrives while spinning
            node.create_subscription(String, "spinning_lean/topic", on_message, 10)
        if len(seen) > 3:
            publisher.publish(String(data="hello"))

    async def on_message(message):
        seen.append("awaited " + message.data)

    publisher = node.create_publisher(String, "spinning_lean/topic", 10)
    node.create_timer(0.02, tick)
    try:
        until = lambda: any(s.startswith("awaited") for s in seen)
        spin_nodes([node], until=until, timeout=10, lean=LEAN)
    except Exception as error:
        print(type(error).__name__, error, flush=True)
    print(" ".join(dict.fromkeys(seen)), flush=True)
    rclpy.try_shutdown()
    """
)


def spin_lean(lean: bool | None) -> subprocess.CompletedProcess[str]:
    program = LEAN_BY_DEFAULT.format(lean=lean)
    return subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=60
    )


def test_spin_nodes_spins_lean_until_a_node_has_what_only_rclpy_serves() -> None:
    """By default WaitLoop spins the nodes; a coroutine callback created while spinning
    hands them to rclpy's executor (which awaits it), with one log line naming it."""
    done = spin_lean(None)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[0] == "lean rclpy awaited hello", done.stdout + done.stderr
    fallbacks = [line for line in done.stderr.splitlines() if "spinning with rclpy" in line]
    assert len(fallbacks) == 1, done.stderr
    assert (
        "node /spinning_lean_test: the subscription /spinning_lean/topic has a coroutine"
        in (fallbacks[0])
    )


def test_spin_nodes_lean_true_refuses_and_lean_false_is_rclpy_throughout() -> None:
    done = spin_lean(True)
    assert done.stdout.split("\n")[0].startswith(
        "UnsupportedEntityError node /spinning_lean_test: the subscription"
    ), done.stdout + done.stderr
    assert "(lean=False)" in done.stdout and "spinning with rclpy" not in done.stderr
    done = spin_lean(False)
    assert done.stdout.split("\n")[0] == "rclpy awaited hello", done.stdout + done.stderr
    assert "spinning with rclpy" not in done.stderr
