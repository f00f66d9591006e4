"""A manager refuses to run beside another live manager in its namespace (two would
re-assert over each other's epochs without end), and refuses a state file it cannot write;
a state file that stops being writable later is logged, and the manager keeps running."""

from __future__ import annotations

import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.ros.processes import Child, ProcessGroup
from tests.ros.test_cli import contextros

RIVAL = "another Layer manager is live in namespace {namespace}: id {id}"


@pytest.fixture
def processes() -> Iterator[ProcessGroup]:
    group = ProcessGroup()
    try:
        yield group
    finally:
        group.kill_all()


def in_namespace(namespace: str) -> tuple[str, ...]:
    return ("--ros-args", "-r", f"__ns:={namespace}")


def manager_id(manager: Child) -> str:
    """The id a manager logs as it starts."""
    found = manager.wait_for(
        lambda _: next(
            (m for line in manager.lines if (m := re.search(r"Layer manager (\S+) recov", line))),
            None,
        ),
        10.0,
        "the manager's id",
    )
    return found.group(1)


def epochs(node: Child) -> list[int]:
    return [event["epoch"] for event in node.applied()]


def test_a_second_manager_beside_a_running_one_exits_2_naming_it(
    processes: ProcessGroup,
) -> None:
    namespace = "/guard_second"
    node = processes.participant("p1", *in_namespace(namespace))
    first = processes.manager(*in_namespace(namespace), name="first")
    node.wait_applied(1, timeout=15.0)
    settled = epochs(node)[-1]
    second = processes.manager(*in_namespace(namespace), name="second")
    started = time.monotonic()
    assert second.wait_exit(15.0) == 2, second.output()
    assert time.monotonic() - started < 8.0
    assert RIVAL.format(namespace=namespace, id=manager_id(first)) in second.output()
    assert "Stop the other one, or give this one its own --namespace" in second.output()
    time.sleep(1.0)  # the first manager's heartbeats: still its epoch, none newer
    assert epochs(node)[-1] == settled, node.output()
    assert first.popen.poll() is None
    assert "re-asserted" not in first.output()


def test_two_managers_started_at_once_leave_one_and_the_epoch_settles(
    processes: ProcessGroup,
) -> None:
    namespace = "/guard_twins"
    node = processes.participant("p1", *in_namespace(namespace))
    node.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15.0, "ready")
    twins = [processes.manager(*in_namespace(namespace), name=f"m{i}") for i in (1, 2)]
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and all(m.popen.poll() is None for m in twins):
        time.sleep(0.1)
    exited = [m for m in twins if m.popen.poll() is not None]
    assert len(exited) == 1, "\n".join(m.output() for m in twins)
    assert exited[0].wait_exit() == 2
    (survivor,) = [m for m in twins if m is not exited[0]]
    assert RIVAL.format(namespace=namespace, id=manager_id(survivor)) in exited[0].output()
    node.wait_applied(1, timeout=10.0)
    time.sleep(1.0)
    settled = epochs(node)[-1]
    time.sleep(1.5)
    assert epochs(node)[-1] == settled
    assert len(set(epochs(node))) <= 20, epochs(node)  # not a storm (thousands before)


def test_an_unwritable_state_file_is_refused_at_start(tmp_path: Path) -> None:
    missing = tmp_path / "no_such_dir" / "state.json"
    run = contextros("manager", "--state-file", str(missing), "--recovery-window", "0.1")
    assert run.returncode == 2, run.stderr
    assert f"cannot write the state file {missing}: No such file or directory" in run.stderr
    assert not missing.parent.exists()


def test_a_state_file_that_stops_being_writable_is_logged_and_the_manager_runs_on(
    processes: ProcessGroup, tmp_path: Path
) -> None:
    namespace = "/guard_state_file"
    folder = tmp_path / "state"
    folder.mkdir()
    state_file = folder / "state.json"
    manager = processes.manager(
        "--state-file", str(state_file), *in_namespace(namespace), name="manager"
    )
    first = processes.participant("p1", *in_namespace(namespace))
    first.wait_applied(1, timeout=15.0)
    assert state_file.exists()
    shutil.rmtree(folder)  # (as root, a read-only folder would still take the file)
    second = processes.participant("p2", *in_namespace(namespace))  # a join is saved
    manager.wait_for(
        lambda _: any("not written" in line for line in manager.lines), 10.0, "the error"
    )
    third = processes.participant("p3", *in_namespace(namespace))  # fails alike: not again
    time.sleep(1.5)
    assert second.popen.poll() is None and third.popen.poll() is None
    errors = [line for line in manager.lines if "not written" in line]
    assert len(errors) == 1, manager.output()
    assert f"state file {state_file} not written" in errors[0]
    assert "No such file or directory" in errors[0]
    assert manager.popen.poll() is None
