"""Layered functions and methods: composition order, proceed, transparency, errors."""

from __future__ import annotations

import asyncio
import inspect
import traceback

import pytest

from contextros import (
    Layer,
    LayerDefinitionError,
    NoImplementationError,
    ProceedError,
    activate,
    deactivate,
    layered,
    proceed,
    set_active,
)
from contextros.core import layered_function_of

A, B, C, Idle = Layer("A"), Layer("B"), Layer("C"), Layer("Idle")


class Robot:
    def __init__(self) -> None:
        self.calls: list[str] = []

    @layered
    def describe(self, x: int) -> list[str]:
        return [f"base({x})"]

    @describe.partial(A)
    def describe(self, x: int) -> list[str]:
        return ["A", *proceed(self, x)]

    @describe.partial(B)
    def describe(self, x: int) -> list[str]:
        return ["B", *proceed(self, x + 1)]

    @describe.partial(C)
    def describe(self, x: int) -> list[str]:
        return ["C"]  # does not proceed


def test_base_runs_with_no_active_layer() -> None:
    assert Robot().describe(1) == ["base(1)"]


def test_newest_activated_layer_is_outermost() -> None:
    activate(A)
    activate(B)
    assert Robot().describe(1) == ["B", "A", "base(2)"]
    set_active([B, A])
    assert Robot().describe(1) == ["A", "B", "base(2)"]


def test_a_partial_that_does_not_proceed_hides_the_rest() -> None:
    activate(A, C)
    assert Robot().describe(0) == ["C"]


def test_layer_without_a_partial_is_transparent() -> None:
    activate(A, Idle)
    assert Robot().describe(0) == ["A", "base(0)"]


def test_bound_methods_captured_before_a_switch_follow_it() -> None:
    robot = Robot()
    callback = robot.describe  # as a ROS timer would hold it
    activate(A)
    assert callback(0) == ["A", "base(0)"]
    deactivate(A)
    assert callback(0) == ["base(0)"]


def test_identity_and_metadata_survive_switches() -> None:
    before = Robot.describe
    activate(A, B)
    assert Robot.describe is before
    assert Robot.describe.__name__ == "describe"
    assert Robot.describe.__qualname__ == "Robot.describe"
    assert list(inspect.signature(Robot.describe).parameters) == ["self", "x"]
    assert layered_function_of(Robot.describe) is not None
    assert layered_function_of(len) is None


# -- free functions (the paper's getPos) -------------------------------------------------

Indoor = Layer("Indoor", group="location")
Outdoor = Layer("Outdoor", group="location")


@layered(base=False)
def get_pos() -> str:
    """Where the robot is."""


@get_pos.partial(Indoor)
def get_pos() -> str:
    return "gyro"


@get_pos.partial(Outdoor)
def get_pos() -> str:
    return "gps"


def test_free_function_dispatches_on_the_active_layer() -> None:
    activate(Indoor)
    assert get_pos() == "gyro"
    activate(Outdoor)
    assert get_pos() == "gps"
    assert get_pos.__doc__ == "Where the robot is."


def test_no_base_and_no_partial_names_the_method_and_active_layers() -> None:
    activate(Idle)
    with pytest.raises(
        NoImplementationError, match=r"get_pos\(\) has no base .*active layers: Idle"
    ):
        get_pos()


@layered(base=False)
def only_partials() -> str: ...


@only_partials.partial(A)
def only_partials() -> str:
    return "A>" + proceed()


def test_proceed_past_the_last_implementation_names_layer_and_method() -> None:
    activate(A)
    with pytest.raises(ProceedError, match="proceed\\(\\) in layer A's partial of only_partials"):
        only_partials()


def test_proceed_outside_a_partial_is_a_clear_error() -> None:
    with pytest.raises(ProceedError, match="outside a partial"):
        proceed()


def test_duplicate_partial_is_rejected_unless_replacing() -> None:
    @layered
    def f() -> int:
        return 0

    f.partial(A)(lambda: 1)
    with pytest.raises(LayerDefinitionError, match="already has a partial for layer A"):

        @f.partial(A)
        def f2() -> int:
            return 2

    @f.partial(A, replace=True)
    def f3() -> int:
        return 3

    activate(A)
    assert f() == 3


def test_layered_rejects_non_functions() -> None:
    with pytest.raises(LayerDefinitionError, match="plain functions"):
        layered(len)  # type: ignore[arg-type]


def test_partial_reaching_proceed_indirectly_still_works() -> None:
    import contextros

    @layered
    def g(x: int) -> int:
        return x

    @g.partial(A)
    def g(x: int) -> int:
        return contextros.proceed(x) + 100  # attribute access: the context-variable path

    activate(A)
    assert g(1) == 101


def test_proceed_inside_a_nested_function_and_with_keywords() -> None:
    @layered
    def h(x: int, *, scale: int = 1) -> int:
        return x * scale

    @h.partial(B)
    def h(x: int, *, scale: int = 1) -> int:
        return sum(proceed(i, scale=scale) for i in range(x))

    activate(B)
    assert h(3, scale=2) == 0 + 2 + 4


def test_attribute_named_proceed_is_left_alone() -> None:
    class Job:
        def proceed(self) -> str:
            return "job"

    @layered
    def run(job: Job) -> str:
        return "base"

    @run.partial(A)
    def run(job: Job) -> str:
        return job.proceed() + "+" + proceed(job)

    activate(A)
    assert run(Job()) == "job+base"


def test_partials_with_super_and_default_arguments() -> None:
    class Base:
        def speed(self) -> int:
            return 1

    class Fast(Base):
        @layered
        def speed(self, factor: int = 2) -> int:
            return super().speed() * factor

        @speed.partial(A)
        def speed(self, factor: int = 2) -> int:
            return proceed(self, factor) + super().speed()

        @speed.partial(B)
        def speed(self, factor: int = 10) -> int:  # other default: trampoline path
            return proceed(self, factor)

    activate(A)
    assert Fast().speed() == 3
    activate(B)
    assert Fast().speed() == 11
    assert Fast().speed(3) == 4


def test_tracebacks_point_at_the_partial_source() -> None:
    @layered
    def boom() -> None:
        return None

    @boom.partial(A)
    def boom() -> None:
        raise RuntimeError("inside A")

    activate(A)
    with pytest.raises(RuntimeError) as caught:
        boom()
    frames = traceback.extract_tb(caught.value.__traceback__)
    assert frames[-1].filename == __file__
    assert frames[-1].line == 'raise RuntimeError("inside A")'


def test_async_partials_proceed_to_async_base() -> None:
    @layered
    async def fetch() -> str:
        return "base"

    @fetch.partial(A)
    async def fetch() -> str:
        return "A+" + await proceed()

    activate(A)
    assert asyncio.run(fetch()) == "A+base"
