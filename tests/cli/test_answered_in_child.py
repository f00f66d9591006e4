"""A command's own ROS client runs in a forked child: its answer and exit status do not
depend on how the child's teardown ends (hung or crashed), and a child that ends without
an answer is reported, not waited for. Each case runs in a fresh process of its own, as
a command does (this test process runs threads, so it would not fork). The child's
teardown writes to a file: the two processes' standard output would interleave."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

PROGRAM = textwrap.dedent(
    """
    import json, os, signal, sys, time
    from contextros.cli.answered_in_child import answered_in_child

    def work(teardown):
        teardown.callback(lambda: open(sys.argv[1], "w").write(str(os.getpid())))
        BEFORE
        teardown.callback(lambda: IN_TEARDOWN)
        return {"outcome": "result", "pid": os.getpid()}

    print(json.dumps({"parent": os.getpid()}), flush=True)
    with answered_in_child(work, "the outcome is unknown", limit=LIMIT) as answer:
        print(json.dumps(answer), flush=True)
    print(json.dumps({"reaped": True}), flush=True)
    """
)


def run(
    tmp_path: Path, before: str = "pass", in_teardown: str = "None", limit: float = 10.0
) -> tuple[dict[str, Any], str]:
    """What the program printed, by key, and its standard error; "torn_down_by": the pid
    of the process that tore its node down, if one did."""
    program = PROGRAM.replace("BEFORE", before).replace("IN_TEARDOWN", in_teardown)
    program = program.replace("LIMIT", str(limit))
    torn = tmp_path / "torn_down_by"
    done = subprocess.run(
        [sys.executable, "-c", program, str(torn)], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    printed: dict[str, Any] = {}
    for line in done.stdout.splitlines():
        record = json.loads(line)
        key = "answer" if "outcome" in record else next(iter(record))
        printed[key] = record if key == "answer" else record[key]
    assert printed["reaped"] is True, "the block ended"
    if torn.exists():
        printed["torn_down_by"] = int(torn.read_text())
    return printed, done.stderr


def test_the_answer_comes_from_a_child_that_tears_down_after_answering(tmp_path: Path) -> None:
    printed, _ = run(tmp_path)
    assert printed["answer"]["outcome"] == "result"
    child = printed["answer"]["pid"]
    assert child != printed["parent"], "asked from another process"
    assert printed["torn_down_by"] == child, "the child tore its node down"


def test_a_teardown_that_hangs_is_killed_and_the_answer_stands(tmp_path: Path) -> None:
    printed, _ = run(tmp_path, in_teardown="time.sleep(600)", limit=0.5)
    assert printed["answer"]["outcome"] == "result"
    assert "torn_down_by" not in printed, "the hung teardown never ended"


def test_a_teardown_that_crashes_leaves_the_answer_and_no_crash_report(tmp_path: Path) -> None:
    printed, stderr = run(tmp_path, in_teardown="os.kill(os.getpid(), signal.SIGSEGV)")
    assert printed["answer"]["outcome"] == "result"
    assert "Segmentation fault" not in stderr, stderr


def test_a_child_that_dies_before_answering_is_reported_with_its_signal(tmp_path: Path) -> None:
    printed, stderr = run(tmp_path, before="os.kill(os.getpid(), signal.SIGSEGV)")
    answer = printed["answer"]
    assert answer["outcome"] == "failed"
    assert "killed by SIGSEGV without an answer; the outcome is unknown" in answer["message"]
    assert "Fatal Python error: Segmentation fault" in stderr, "where it crashed is shown"


def test_a_child_that_raises_shows_its_traceback_and_is_reported(tmp_path: Path) -> None:
    printed, stderr = run(tmp_path, before="raise RuntimeError('no luck')")
    assert printed["answer"]["outcome"] == "failed"
    assert "failed: RuntimeError: no luck (traceback above)" in printed["answer"]["message"]
    assert "Traceback" in stderr and "RuntimeError: no luck" in stderr


def test_an_error_is_reported_as_one_even_when_teardown_shuts_rclpy_down(
    tmp_path: Path,
) -> None:
    """Ctrl-C shows as a context that rclpy's signal handler shut down; a real error is
    judged before teardown shuts the context down itself."""
    fake_rclpy = (
        "import types; context = {'ok': True}; "
        "sys.modules['rclpy'] = types.SimpleNamespace(ok=lambda: context['ok']); "
        "teardown.callback(context.update, ok=False); "
        "raise RuntimeError('a bug')"
    )
    printed, stderr = run(tmp_path, before=fake_rclpy)
    assert printed["answer"]["outcome"] == "failed", printed
    assert "failed: RuntimeError: a bug" in printed["answer"]["message"]
    assert "RuntimeError: a bug" in stderr


def test_a_child_that_fails_is_not_waited_for_through_its_teardown(tmp_path: Path) -> None:
    printed, stderr = run(
        tmp_path,
        before="teardown.callback(time.sleep, 600); raise RuntimeError('no luck')",
        limit=0.5,
    )
    assert printed["answer"]["outcome"] == "failed", "reported before the teardown ended"
    assert "RuntimeError: no luck" in stderr


def test_a_child_dies_with_the_command(tmp_path: Path) -> None:
    """Killing the command (a supervisor, a timeout) kills its ROS client too."""
    pid_file = tmp_path / "child"
    program = PROGRAM.replace(
        "BEFORE", f"open({str(pid_file)!r}, 'w').write(str(os.getpid())); time.sleep(600)"
    ).replace("LIMIT", "10.0")
    command = subprocess.Popen([sys.executable, "-c", program, str(tmp_path / "torn")])
    try:
        deadline = time.monotonic() + 30
        while not pid_file.exists() or not pid_file.read_text():
            assert time.monotonic() < deadline, "the child did not start"
            time.sleep(0.05)
        child = int(pid_file.read_text())
        assert _alive(child)
    finally:
        command.kill()
        command.wait()
    deadline = time.monotonic() + 10
    while _alive(child):
        assert time.monotonic() < deadline, f"child {child} outlived the command"
        time.sleep(0.05)


def _alive(pid: int) -> bool:
    """Running, not merely a zombie that nobody reaped yet."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")
