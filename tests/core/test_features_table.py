"""Rows of the COP feature table in docs/core.md that no other test covers by itself."""

from __future__ import annotations

import asyncio

from contextros import Layer, activate, activated, layered, proceed, set_active

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
