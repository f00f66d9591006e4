"""What a context node, C++ or Python, logs about the manager's liveness says what happened: a node
started before any manager never "lost" one and does not hear it "again" (issue 25: a C++
node started with the manager logged `no Layer manager heard for 3.0 s`, then `Layer
manager  heard again`, having never heard it); a manager heard, lost and back is."""

from __future__ import annotations

import re
import signal

from tests.ros.processes import Child, ProcessGroup


def wait_line(child: Child, text: str, timeout: float) -> str:
    return child.wait_for(
        lambda _: next((line for line in child.lines if text in line), None), timeout, repr(text)
    )


def test_a_manager_first_heard_is_not_heard_again_and_one_back_is(
    processes: ProcessGroup,
) -> None:
    nodes = [processes.cpp_participant("cxx_alone"), processes.participant("py_alone")]
    for node in nodes:
        silent = wait_line(node, "no Layer manager heard", 15)
        assert re.search(
            r"no Layer manager heard in the first 3\.\d s: keeping layers \[\] \(epoch 0\)", silent
        )

    first = processes.manager("--recovery-window", "0.2", name="first manager")
    for node in nodes:
        found = wait_line(node, "heard for the first time", 15)
        assert "Layer manager " in found and "  heard" not in found, "names the manager"
        node.wait_applied(1)
        assert not any("heard again" in line for line in node.lines), node.output()

    first.signal(signal.SIGKILL)
    first.wait_exit()
    for node in nodes:
        lost = wait_line(node, "no Layer manager heard for", 15)
        assert "keeping layers [] (epoch 1)" in lost
    processes.manager("--recovery-window", "0.2", name="second manager")
    for node in nodes:
        again = wait_line(node, "heard again", 15)
        assert "for the first time" not in again
