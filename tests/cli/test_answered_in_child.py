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
    with answered_in_child(work, "the outcome is unknown", limit=0.5) as answer:
        print(json.dumps(answer), flush=True)
    print(json.dumps({"reaped": True}), flush=True)
    """
)


def run(
    tmp_path: Path, before: str = "pass", in_teardown: str = "None"
) -> tuple[dict[str, Any], str]:
    """What the program printed, by key, and its standard error; "torn_down_by": the pid
    of the process that tore its node down, if one did."""
    program = PROGRAM.replace("BEFORE", before).replace("IN_TEARDOWN", in_teardown)
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
    printed, _ = run(tmp_path, in_teardown="time.sleep(600)")
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
    assert "exited with status 1 without an answer" in printed["answer"]["message"]
    assert "RuntimeError: no luck" in stderr
