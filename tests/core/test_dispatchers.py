"""Both dispatchers of the scoped and per-receiver paths: the C one (`_dispatch.c`), selected
at import when built, and the pure-Python one (CONTEXTROS_PURE_PYTHON=1, or no extension).
The core's tests run under the one selected here; the test below runs them under the other."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import traceback
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


def test_a_stale_build_falls_back_to_pure_python_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it)")
    from contextros.core import _dispatch, composition

    monkeypatch.delenv("CONTEXTROS_PURE_PYTHON", raising=False)
    assert composition._finder_type() is _dispatch.Finder
    monkeypatch.setattr(_dispatch, "ABI", 0)
    with pytest.warns(RuntimeWarning, match="built from other sources"):
        assert composition._finder_type() is None


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


B = Layer("DispatchersB")


def _helper_proceeds(self: object, factor: int) -> int:
    from contextros import proceed as helper_proceed

    return helper_proceed(self, factor)


class Arm:
    @layered
    def reach(self, factor: int) -> int:
        if factor < 0:
            raise ValueError(f"negative: {factor}")
        return factor

    @reach.partial(A)
    def reach(self, factor: int) -> int:
        if factor > 1000:
            raise ValueError(f"too far: {factor}")
        return proceed(self, factor) * 10

    @reach.partial(B)
    def reach(self, factor: int) -> int:
        return _helper_proceeds(self, factor) + 1


def test_calls_whose_head_is_not_the_one_the_dispatcher_expects() -> None:
    """The C dispatcher runs the head it expects (the newest scope's, the receiver changed
    last) in its own frame and calls any other: every mix gives each call its own chain."""
    a, b, plain = Arm(), Arm(), Arm()
    activate_for(a, A)
    activate_for(b, B)  # expected: b's head
    try:
        assert [x.reach(2) for x in (a, b, plain, b, a)] == [20, 3, 2, 3, 20]
        with activated(B):  # expected: the scope's head; a adds A inside it
            assert [x.reach(2) for x in (a, b, plain)] == [21, 3, 3]
            with activated(A):
                assert [x.reach(2) for x in (a, b, plain)] == [21, 30, 30]
    finally:
        reset_for(a)
        reset_for(b)
    with activated(A):
        assert plain.reach(3) == 30
    with activated(B):
        assert plain.reach(3) == 4


def test_the_expected_head_runs_in_the_dispatchers_frame() -> None:
    """With the C dispatcher, a scoped call of the newest scope's chain has no frame of its
    own before the partial's (pure Python: one dispatcher frame)."""
    arm = Arm()
    try:
        with activated(A):
            arm.reach(2000)
    except ValueError as error:  # its frames are not kept: a kept scope would stay alive
        frames = traceback.extract_tb(error.__traceback__)
    assert frames[-1].line == 'raise ValueError(f"too far: {factor}")'
    dispatchers = [frame for frame in frames if frame.filename.startswith("<contextros")]
    assert len(dispatchers) == (1 if contextros.core.DISPATCHER == "python" else 0)
    assert [frame.name for frame in frames[1:]] == (
        ["reach", "reach"] if contextros.core.DISPATCHER == "python" else ["reach"]
    )
