"""before/after/around partials over proceed, and removing partials and layers at run time."""

from __future__ import annotations

import asyncio

import pytest

from contextros import (
    Layer,
    LayerDefinitionError,
    RelationError,
    UnknownLayerError,
    activate,
    activated,
    active_layers,
    critical,
    layer_named,
    layered,
    proceed,
    remove_layer,
)
from contextros.core import layered_function_of

Logged, Doubled, Wrapped = Layer("Logged"), Layer("Doubled"), Layer("Wrapped")


class Arm:
    def __init__(self) -> None:
        self.log: list[str] = []

    @layered
    def move(self, x: int) -> int:
        self.log.append(f"move {x}")
        return x

    @move.before(Logged)
    def move(self, x: int) -> None:
        self.log.append(f"before {x}")

    @move.after(Doubled)
    def move(self, x: int, *, result: int) -> int:
        self.log.append(f"after {result}")
        return result * 2

    @move.around(Wrapped)
    def move(self, x: int) -> int:
        return proceed(self, x + 1) - 1


def test_before_runs_first_with_the_same_arguments() -> None:
    arm = Arm()
    activate(Logged)
    assert arm.move(3) == 3
    assert arm.log == ["before 3", "move 3"]


def test_after_gets_the_result_and_replaces_it() -> None:
    arm = Arm()
    activate(Doubled)
    assert arm.move(3) == 6
    assert arm.log == ["move 3", "after 3"]


def test_around_is_partial_and_all_three_compose_in_activation_order() -> None:
    arm = Arm()
    activate(Doubled, Logged, Wrapped)  # Wrapped outermost, then Logged, then Doubled
    assert arm.move(3) == (4 * 2) - 1
    assert arm.log == ["before 4", "move 4", "after 4"]


def test_async_before_and_after() -> None:
    @layered
    async def fetch(x: int) -> int:
        return x

    seen: list[int] = []

    @fetch.before(Logged)
    async def fetch(x: int) -> None:
        seen.append(x)

    @fetch.after(Doubled)
    def fetch(x: int, *, result: int) -> int:
        return result * 2

    activate(Logged, Doubled)
    assert asyncio.run(fetch(5)) == 10 and seen == [5]


def test_removing_a_partial_rewires_calls_at_once_scopes_included() -> None:
    @layered
    def level() -> str:
        return "base"

    @level.partial(Logged)
    def level() -> str:
        return "logged>" + proceed()

    activate(Logged)
    with activated(Wrapped):  # a scope alive: its cached heads must be rewired too
        assert level() == "logged>base"
        level.remove_partial(Logged)  # type: ignore[attr-defined]
        assert level() == "base"
    assert level() == "base"
    with pytest.raises(LayerDefinitionError, match="has no partial for layer Logged"):
        level.remove_partial(Logged)  # type: ignore[attr-defined]


def test_removing_a_layer_deactivates_it_and_drops_its_partials_everywhere() -> None:
    Temporary = Layer("Temporary")

    @layered
    def one() -> str:
        return "one"

    @one.partial(Temporary)
    def one() -> str:
        return "T1"

    @layered
    def two() -> str:
        return "two"

    @two.partial(Temporary)
    def two() -> str:
        return "T2"

    activate(Temporary, Logged)
    assert (one(), two()) == ("T1", "T2")
    refined = remove_layer(Temporary)
    assert {name.rsplit(".", 1)[-1] for name in refined} == {"one", "two"}
    assert (one(), two()) == ("one", "two")
    assert [layer.name for layer in active_layers()] == ["Logged"]
    with pytest.raises(UnknownLayerError):
        layer_named("Temporary")
    owner = layered_function_of(one)
    assert owner is not None and "Temporary" not in owner.partials


def test_removing_a_required_layer_is_refused_and_changes_nothing() -> None:
    Base_ = Layer("Footing")
    Layer("Climbing", requires=["Footing"])
    activate(Base_)
    activate("Climbing")
    with pytest.raises(RelationError, match="Climbing requires Footing"):
        remove_layer(Base_)
    assert layer_named("Footing") == Base_
    with critical(), pytest.raises(LayerDefinitionError, match="critical section"):
        remove_layer("Climbing")


def test_after_advice_in_the_old_form_is_refused_with_the_new_one_to_write() -> None:
    @layered
    def move(x: int) -> int:
        return x

    with pytest.raises(LayerDefinitionError, match=r"result first .*def move\(x, \*, result\)"):

        @move.after(Doubled)
        def move(result: int, x: int) -> int:
            return result


def test_after_advice_without_a_result_parameter_is_refused() -> None:
    @layered
    def move(x: int) -> int:
        return x

    with pytest.raises(LayerDefinitionError, match="no parameter 'result'"):

        @move.after(Doubled)
        def move(x: int) -> int:
            return x


def test_after_advice_may_take_the_result_in_its_keywords() -> None:
    class Arm:
        @layered
        def move(self, x: int) -> int:
            return x

        @move.after(Doubled)
        def move(self, x: int, **extra: int) -> int:
            return extra["result"] + 1

    activate(Doubled)
    assert Arm().move(4) == 5
