"""Both dispatchers of the scoped and per-receiver paths: the C one (`_dispatch.c`), selected
at import when built, and the pure-Python one (CONTEXTROS_PURE_PYTHON=1, or no extension).
The core's tests run under the one selected here; the test below runs them under the other."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

import contextros.core
from contextros.core import Layer, activate_for, activated, layered, proceed, reset_for

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
BUILT = importlib.util.find_spec("contextros.core._dispatch") is not None
FORCED_PURE = os.environ.get("CONTEXTROS_PURE_PYTHON", "") not in ("", "0")


def _dispatcher_of(environment: dict[str, str]) -> str:
    return subprocess.run(
        [sys.executable, "-c", "import contextros.core as c; print(c.DISPATCHER)"],
        env=os.environ | environment,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()


def test_the_c_dispatcher_is_selected_when_built_and_pure_python_on_request() -> None:
    selected = contextros.core.DISPATCHER
    assert selected == ("c" if BUILT and not FORCED_PURE else "python")
    assert _dispatcher_of({"CONTEXTROS_PURE_PYTHON": "1"}) == "python"
    assert _dispatcher_of({"CONTEXTROS_PURE_PYTHON": "0"}) == ("c" if BUILT else "python")


def test_the_core_tests_pass_under_the_other_dispatcher() -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it): only pure Python here")
    other = "0" if FORCED_PURE else "1"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-p",
            "no:xdist",
            str(HERE),
            f"--ignore={Path(__file__)}",
        ],
        env=os.environ | {"CONTEXTROS_PURE_PYTHON": other},
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=110,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert " passed" in done.stdout.splitlines()[-1]


A = Layer("DispatchersA")


class Robot:
    @layered
    def speed(self, factor: int, *, boost: int = 0) -> int:
        return factor + boost

    @speed.partial(A)
    def speed(self, factor: int, *, boost: int = 0) -> int:
        return proceed(self, factor, boost=boost) * 10


class Loose:
    """Partials whose parameters differ from the base's: the `*args, **kwargs` dispatchers."""

    @layered
    def speed(self, factor: int, boost: int = 0) -> int:
        return factor + boost

    @speed.partial(A)
    def speed(self, *args: int, **kwargs: int) -> int:
        return proceed(self, *args, **kwargs) * 10


@pytest.mark.parametrize("cls", [Robot, Loose])
def test_scoped_per_object_and_class_wide_calls_with_keywords(cls: type) -> None:
    r, other = cls(), cls()
    assert r.speed(1, boost=2) == 3
    with activated(A):
        assert r.speed(1, boost=2) == 30
        assert cls.speed(r, 1) == 10  # the receiver passed positionally, through the class
    activate_for(r, A)
    try:
        assert (r.speed(1, boost=2), other.speed(1, boost=2)) == (30, 3)
        with activated(A):
            assert other.speed(2) == 20
        activate_for(cls, A)
        assert other.speed(2) == 20
    finally:
        reset_for(r)
        reset_for(cls)
    assert r.speed(1) == 1


def test_a_call_with_no_receiver_on_the_per_receiver_path_names_what_is_missing() -> None:
    r = Loose()
    activate_for(r, A)
    try:
        with pytest.raises(TypeError, match="speed"):
            Loose.speed()
    finally:
        reset_for(r)
