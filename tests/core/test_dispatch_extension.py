"""The C dispatcher's extension (`_dispatch.c`): its build by make, and its Finder used
wrongly from Python (a TypeError, never a crash; each case runs in a process of its own, so
a crash fails the test, not pytest)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILT = importlib.util.find_spec("contextros.core._dispatch") is not None

MADE = """
import contextvars
import types
from contextros.core._dispatch import Finder

def made():
    runtime = types.SimpleNamespace(_live_scopes=True)  # a scope alive: no direct path
    return Finder(len, contextvars.ContextVar("scope"), runtime, len)
"""


@pytest.mark.parametrize(
    ("use", "message"),
    [
        ("Finder.__new__(Finder)[None]", "not initialised"),
        ("Finder.__new__(Finder)[object()]", "not initialised"),
        ("Finder.__new__(Finder)()", "not initialised"),
        ("Finder.__new__(Finder)(object())", "not initialised"),
        ("made()(1, 2)", "at most one argument"),
        ("made().__init__(len, contextvars.ContextVar('s'), 1, len)", "already initialised"),
    ],
)
def test_a_finder_used_wrongly_raises_a_type_error(use: str, message: str) -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it)")
    program = (
        MADE
        + f"""
try:
    {use}
except TypeError as error:
    print("TypeError:", error)
else:
    print("no error")
"""
    )
    done = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.startswith("TypeError:") and message in done.stdout, done.stdout


def test_an_initialised_finder_finds_the_head() -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it)")
    program = MADE + "print(made()() is len, made()[None] is len)"
    done = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=30
    )
    assert (done.returncode, done.stdout.split()) == (0, ["True", "True"]), done.stderr


FAKE_CMAKE = """#!/bin/sh
# cmake --build DIR --target dispatch_extension: builds DIR/dispatch/_dispatch.x.so, or fails.
[ -f fails ] && exit 1
mkdir -p "$2/dispatch" && echo built > "$2/dispatch/_dispatch.x.so"
"""


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_make_builds_the_dispatcher_again_after_a_failed_build(tmp_path: Path) -> None:
    """A failed build warns and make succeeds (pure Python still works), but leaves no
    stamp: the next make builds it. The Makefile runs in a directory of its own, with a
    cmake that fails while `fails` exists."""
    (tmp_path / "src/contextros/core").mkdir(parents=True)
    shutil.copy(ROOT / "src/contextros/core/_dispatch.c", tmp_path / "src/contextros/core")
    (tmp_path / ".venv/bin").mkdir(parents=True)
    cmake = tmp_path / ".venv/bin/cmake"
    cmake.write_text(FAKE_CMAKE)
    cmake.chmod(0o755)
    stamp, interfaces = tmp_path / ".venv/.stamp-dispatch", tmp_path / ".venv/.stamp-interfaces"
    interfaces.touch()
    os.utime(interfaces, (0, 0))
    built = tmp_path / "src/contextros/core/_dispatch.x.so"

    def make() -> str:
        done = subprocess.run(
            [
                "make",
                "-s",
                "-f",
                str(ROOT / "Makefile"),
                "-o",
                ".venv/.stamp-interfaces",
                "WHEEL_BUILD=build",
                ".venv/.stamp-dispatch",
            ],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        return done.stdout

    (tmp_path / "fails").touch()
    assert "WARNING: the C dispatcher was not built" in make()
    assert not stamp.exists() and not built.exists()
    assert "WARNING" in make()  # tried again
    (tmp_path / "fails").unlink()
    assert "WARNING" not in make()
    assert stamp.exists() and built.read_text() == "built\n"
