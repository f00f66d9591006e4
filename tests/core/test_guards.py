"""Guards: a partial that applies only while a condition on its call holds (`when=`).

Includes ContextPy3's guards ported: there a guard is a condition on the active layers, checked
when the chain is composed; here it is a condition on each call (its arguments), which can
read the active layers too.
"""

from __future__ import annotations

import asyncio
import linecache
import traceback

import pytest

from contextros import (
    Layer,
    LayerDefinitionError,
    NoImplementationError,
    activate,
    activate_for,
    activated,
    active_layers,
    layered,
    proceed,
    set_active,
)

Big, Wet, Logged = Layer("GuardBig"), Layer("GuardWet"), Layer("GuardLogged")


class Cleaner:
    def __init__(self) -> None:
        self.log: list[str] = []

    @layered
    def clean(self, area: int) -> str:
        return f"base {area}"

    @clean.partial(Big, when=lambda self, area: area > 10)
    def clean(self, area: int) -> str:
        return "big " + proceed(self, area)

    @clean.partial(Wet, when=lambda self, area: area % 2 == 0)
    def clean(self, area: int) -> str:
        return "wet " + proceed(self, area)


def test_a_guarded_partial_applies_only_while_its_condition_holds() -> None:
    cleaner = Cleaner()
    with activated(Big):
        assert cleaner.clean(20) == "big base 20"
        assert cleaner.clean(5) == "base 5"  # skipped: the call goes on to the base
    activate(Big)
    assert cleaner.clean(11) == "big base 11"
    assert cleaner.clean(3) == "base 3"


def test_guards_compose_with_proceed_in_activation_order() -> None:
    cleaner = Cleaner()
    activate(Big, Wet)  # Wet newest: outermost
    assert cleaner.clean(20) == "wet big base 20"
    assert cleaner.clean(12) == "wet big base 12"
    assert cleaner.clean(13) == "big base 13"  # Wet's guard false: straight to Big
    assert cleaner.clean(4) == "wet base 4"  # Big's guard false: Wet proceeds to the base
    assert cleaner.clean(3) == "base 3"


def test_guards_apply_to_per_object_activation() -> None:
    mine, other = Cleaner(), Cleaner()
    activate_for(mine, Big)
    assert mine.clean(30) == "big base 30" and mine.clean(1) == "base 1"
    assert other.clean(30) == "base 30"


def test_a_guard_on_before_after_and_around() -> None:
    class Arm:
        def __init__(self) -> None:
            self.log: list[str] = []

        @layered
        def move(self, x: int) -> int:
            return x

        @move.before(Logged, when=lambda self, x: x > 0)
        def move(self, x: int) -> None:
            self.log.append(f"before {x}")

        @move.after(Big, when=lambda self, x: x > 100)
        def move(self, x: int, *, result: int) -> int:
            return result * 2

        @move.around(Wet, when=lambda self, x: x < 0)
        def move(self, x: int) -> int:
            return -proceed(self, -x)

    arm = Arm()
    activate(Logged, Big, Wet)
    assert arm.move(5) == 5 and arm.log == ["before 5"]
    assert arm.move(200) == 400
    assert arm.move(-3) == -3 and arm.log == ["before 5", "before 200", "before 3"]


def test_a_guard_sees_the_defaults_of_the_call() -> None:
    @layered
    def speed(limit: float = 1.0) -> float:
        return limit

    @speed.partial(Big, when=lambda limit=1.0: limit >= 1.0)
    def speed(limit: float = 1.0) -> float:
        return proceed(limit) * 10

    activate(Big)
    assert speed() == 10.0 and speed(0.5) == 0.5


def test_a_false_guard_without_a_base_is_no_implementation() -> None:
    @layered(base=False)
    def plan(n: int) -> str:
        """No base."""
        return ""

    @plan.partial(Big, when=lambda n: n > 0)
    def plan(n: int) -> str:
        return f"plan {n}"

    activate(Big)
    assert plan(2) == "plan 2"
    with pytest.raises(NoImplementationError, match="plan"):
        plan(-1)


def test_async_partials_take_guards() -> None:
    @layered
    async def fetch(x: int) -> int:
        return x

    @fetch.partial(Big, when=lambda x: x > 1)
    async def fetch(x: int) -> int:
        return await proceed(x) * 10

    activate(Big)
    assert asyncio.run(fetch(2)) == 20 and asyncio.run(fetch(1)) == 1


def test_replacing_a_partial_drops_its_guard() -> None:
    @layered
    def level(x: int) -> str:
        return "base"

    @level.partial(Big, when=lambda x: False)
    def level(x: int) -> str:
        return "big"

    activate(Big)
    assert level(1) == "base"

    @level.partial(Big, replace=True)
    def level(x: int) -> str:
        return "big"

    assert level(1) == "big"


def test_a_guard_that_is_not_callable_is_refused() -> None:
    @layered
    def level() -> str:
        return "base"

    with pytest.raises(LayerDefinitionError, match=r"guard .* of .*level.*GuardBig.*callable"):
        level.partial(Big, when=True)  # type: ignore[arg-type]


# -- ContextPy3's guards, ported ---------------------------------------------------------
# ContextPy3: `@around(layer, guard=lambda activelayers: ...)`: the advice is part of the
# chain only while the guard holds on the active layers.


def test_contextpy3_guard_on_the_active_layers() -> None:
    class Greeting:
        @layered
        def greet(self) -> str:
            return "Hello"

        @greet.around(Big, when=lambda self: Wet in active_layers())
        def greet(self) -> str:
            return proceed(self) + " World"

    greeting = Greeting()
    with activated(Big):
        assert greeting.greet() == "Hello"
        with activated(Wet):
            assert greeting.greet() == "Hello World"
        assert greeting.greet() == "Hello"


def _proceed_from_a_helper(self: object, area: int) -> str:
    from contextros import proceed as helper_proceed

    return helper_proceed(self, area)


class Shapes:
    """Guarded partials of every shape: plain ones open with the guard's test in their own
    frame; one with an exception handler, one taking *args, keep a dispatcher."""

    @layered
    def plain(self, area: int) -> str:
        return f"base {area}"

    @plain.partial(Big, when=lambda self, area: area > 10)
    def plain(self, area: int) -> str:
        if area > 1000:
            raise ValueError(f"too big: {area}")
        return "big " + proceed(self, area)

    @plain.partial(Wet, when=lambda self, area: area % 2 == 0)
    def plain(self, area: int) -> str:
        return "wet " + _proceed_from_a_helper(self, area)

    @layered
    def handler(self, area: int) -> str:
        return f"base {area}"

    @handler.partial(Big, when=lambda self, area: area > 10)
    def handler(self, area: int) -> str:
        try:
            return "big " + proceed(self, area)
        except ValueError:
            return "never"

    @layered
    def loose(self, area: int) -> str:
        return f"base {area}"

    @loose.partial(Big, when=lambda self, *args: args[0] > 10)
    def loose(self, *args: int) -> str:
        return "big " + proceed(self, *args)


@pytest.mark.parametrize("method", ["plain", "handler", "loose"])
def test_guarded_partials_of_every_shape(method: str) -> None:
    shapes = Shapes()
    call = getattr(shapes, method)
    with activated(Big):
        assert (call(11), call(3)) == ("big base 11", "base 3")
        if method != "loose":
            assert call(area=12) == "big base 12"


def test_a_guarded_partial_proceeds_from_a_helper_and_under_another_guard() -> None:
    shapes = Shapes()
    with activated(Big, Wet):  # Wet outermost: its guard first
        assert [shapes.plain(n) for n in (12, 11, 4, 3)] == [
            "wet big base 12",
            "big base 11",
            "wet base 4",
            "base 3",
        ]


def test_a_guarded_partial_runs_in_one_frame_with_its_own_lines() -> None:
    """No dispatcher's frame between the call and a plain guarded partial (its traceback
    shows the call, then the partial's line that raised)."""
    shapes = Shapes()
    set_active([Big])
    try:
        shapes.plain(2000)
    except ValueError as error:  # its frames are not kept
        frames = traceback.extract_tb(error.__traceback__)
    finally:
        set_active([])
    assert frames[-1].line == 'raise ValueError(f"too big: {area}")'
    names = [(frame.name, frame.filename) for frame in frames]
    assert not any(path.startswith("<contextros dispatch") for _, path in names), names


LIMIT = 10


class Limits:
    def __init__(self) -> None:
        self.calls = 0

    def above(self, robot: object, area: int) -> bool:
        self.calls += 1
        return area > LIMIT


LIMITS = Limits()


class Guards:
    """Guards of every kind: plain functions of this module run in the partial's frame;
    a bound method, or one taking other parameters, is called."""

    @layered
    def test(self, area: int) -> str:
        return "base"

    @test.partial(Big, when=lambda self, area: area > LIMIT and len(str(area)) < 4)
    def test(self, area: int) -> str:
        return "big " + proceed(self, area)

    @test.partial(Wet, when=lambda self, area: any(d == "7" for d in str(area)))
    def test(self, area: int) -> str:
        return "wet " + proceed(self, area)

    @test.partial(Logged, when=LIMITS.above)
    def test(self, area: int) -> str:
        return "logged " + proceed(self, area)

    @layered
    def failing(self, area: int) -> str:
        return "base"

    @failing.partial(Big, when=lambda self, area: 1 // (area - 5) > 0)
    def failing(self, area: int) -> str:
        return "big"


@pytest.mark.parametrize(
    ("layers", "results"),
    [
        ([Big], ["big base", "base", "base", "big base"]),
        ([Wet], ["base", "base", "wet base", "wet base"]),
        ([Logged], ["logged base", "base", "base", "logged base"]),
        ([Big, Wet, Logged], ["logged big base", "base", "wet base", "logged wet big base"]),
    ],
)
def test_guards_of_every_kind_see_the_call(layers: list[Layer], results: list[str]) -> None:
    guards = Guards()
    set_active(layers)
    try:
        assert [guards.test(area) for area in (11, 3, 7, 17)] == results
    finally:
        set_active([])


def test_a_bound_method_guard_is_called_and_a_guards_error_reaches_the_caller() -> None:
    guards, before = Guards(), LIMITS.calls
    set_active([Logged, Big])
    try:
        guards.test(11)
        assert LIMITS.calls == before + 1
        assert guards.failing(6) == "big"
        assert guards.failing(4) == "base"  # 1 // -1 is -1: the guard is false
        with pytest.raises(ZeroDivisionError):
            guards.failing(5)
    finally:
        set_active([])


def test_an_error_in_an_inlined_guard_points_at_the_guard() -> None:
    guards = Guards()
    set_active([Big])
    try:
        guards.failing(5)
    except ZeroDivisionError as error:  # its frames are not kept
        frames = traceback.extract_tb(error.__traceback__)
    finally:
        set_active([])
    assert frames[-1].line == ("@failing.partial(Big, when=lambda self, area: 1 // (area - 5) > 0)")
    source = linecache.getline(frames[-1].filename, frames[-1].lineno or 0)
    assert source[frames[-1].colno or 0 :].startswith("1 // (area - 5)")


def _scaled_above_ten(robot: object, area: int) -> bool:
    area = area * 100
    return area > 10


def _deleting(robot: object, area: int) -> bool:
    del area
    return True


class Writers:
    """Guards that assign or delete a parameter: their own, never the partial's arguments."""

    @layered
    def test(self, area: int) -> tuple[str, int]:
        return ("base", area)

    @test.partial(Big, when=lambda self, area: (area := area + 10) > 12)
    def test(self, area: int) -> tuple[str, int]:
        return ("big", proceed(self, area)[1])

    @test.partial(Wet, when=_scaled_above_ten)
    def test(self, area: int) -> tuple[str, int]:
        return ("wet", proceed(self, area)[1])

    @test.partial(Logged, when=_deleting)
    def test(self, area: int) -> tuple[str, int]:
        return ("logged", proceed(self, area)[1])


@pytest.mark.parametrize(
    ("layer", "calls"),
    [
        (Big, {3: ("big", 3), 1: ("base", 1)}),
        (Wet, {1: ("wet", 1), 0: ("base", 0)}),
        (Logged, {5: ("logged", 5)}),
    ],
)
def test_a_guard_writing_its_parameters_leaves_the_arguments_alone(
    layer: Layer, calls: dict[int, tuple[str, int]]
) -> None:
    writers = Writers()
    set_active([layer])
    try:
        assert {area: writers.test(area) for area in calls} == calls
    finally:
        set_active([])


def test_a_head_writing_its_parameters_in_the_dispatchers_frame_changes_no_other_call() -> None:
    """The scoped and per-receiver dispatchers run the head they expect in their own frame
    (composition's expected heads): a head assigning or deleting its parameters there
    changes only its own call, and a call finding another head passes its own arguments."""

    class Robot:
        @layered
        def speed(self, n: int) -> tuple[str, int]:
            return ("base", n)

        @speed.partial(Big)
        def speed(self, n: int) -> tuple[str, int]:
            n = n * 100
            return ("big", proceed(self, n)[1])

        @speed.partial(Wet)
        def speed(self, n: int) -> tuple[str, int]:
            del n
            return ("wet", 0)

    robot, other = Robot(), Robot()
    with activated(Big):
        assert [robot.speed(n) for n in (1, 2, 1)] == [("big", 100), ("big", 200), ("big", 100)]
        with activated(Wet):
            assert robot.speed(3) == ("wet", 0)
        assert robot.speed(4) == ("big", 400)
    activate_for(robot, Big)
    assert [robot.speed(1), other.speed(1), robot.speed(2)] == [
        ("big", 100),
        ("base", 1),
        ("big", 200),
    ]
