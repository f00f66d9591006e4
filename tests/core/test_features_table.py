"""Rows of the COP feature table in docs/core.md that no other test covers by itself."""

from __future__ import annotations

import asyncio

from contextros import (
    Layer,
    activate,
    activate_for,
    activated,
    layered,
    proceed,
    reset_for,
    set_active,
)

Tight, Loose = Layer("Tight"), Layer("Loose")


class Gripper:
    @layered
    def grip(self, force: float = 1.0) -> float:
        return force

    @grip.partial(Tight)
    def grip(self, force: float = 5.0) -> float:
        return proceed(self, force)

    @grip.partial(Loose)
    def grip(self, force: float = 0.1) -> float:
        return proceed(self, force)


def test_defaults_of_the_outermost_layer_apply() -> None:
    """Layers that redefine a default: the implementation that runs first (the outermost
    active layer's) binds the arguments, and passes its value on with proceed."""
    gripper = Gripper()
    assert gripper.grip() == 1.0
    activate(Tight)
    assert gripper.grip() == 5.0
    activate(Loose)  # newest: outermost
    assert gripper.grip() == 0.1
    set_active([Loose, Tight])
    assert gripper.grip() == 5.0
    assert gripper.grip(2.0) == 2.0  # an explicit argument always wins


def test_scoped_activation_is_per_asyncio_task() -> None:
    async def in_task(layer: Layer | None) -> float:
        if layer is None:
            await asyncio.sleep(0)
            return Gripper().grip()
        with activated(layer):
            await asyncio.sleep(0)
            return Gripper().grip()

    async def main() -> list[float]:
        return list(await asyncio.gather(in_task(Tight), in_task(Loose), in_task(None)))

    assert asyncio.run(main()) == [5.0, 0.1, 1.0]


def test_defaults_of_the_outermost_layer_apply_in_scopes_and_per_object() -> None:
    """The scoped and per-object dispatchers pass parameters straight on only while every
    implementation has the stub's defaults: redefined defaults still follow the outermost."""
    gripper, other = Gripper(), Gripper()
    with activated(Tight):
        assert gripper.grip() == 5.0
        with activated(Loose):
            assert gripper.grip() == 0.1
    activate_for(gripper, Loose)
    assert gripper.grip() == 0.1 and other.grip() == 1.0
    with activated(Tight):
        assert gripper.grip() == 5.0 and other.grip() == 5.0
    reset_for(gripper)


class Arm:
    @layered
    def reach(self, x: int, /, y: int = 2, *, z: int = 3) -> tuple[int, int, int]:
        return (x, y, z)

    @reach.partial(Tight)
    def reach(self, x: int, /, y: int = 2, *, z: int = 3) -> tuple[int, int, int]:
        a, b, c = proceed(self, x, y, z=z)
        return (a + 10, b, c)


def test_every_kind_of_parameter_passes_through_scoped_and_per_object_calls() -> None:
    arm, other = Arm(), Arm()
    with activated(Tight):
        assert arm.reach(1) == (11, 2, 3)
        assert arm.reach(1, 5, z=7) == (11, 5, 7)
    activate_for(arm, Tight)
    assert arm.reach(1, y=4) == (11, 4, 3) and other.reach(1, z=0) == (1, 2, 0)
    assert "args" not in Arm.reach.__code__.co_varnames  # the exact dispatcher
    with activated(Loose):  # a receiver and a scope: both replayed
        assert arm.reach(2, z=1) == (12, 2, 1) and other.reach(2) == (2, 2, 3)
    reset_for(arm)
