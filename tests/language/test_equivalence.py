"""A compiled layer file behaves exactly like the same program written with the decorators.

The scenario drives fixtures/cleaner.layers and a hand-written decorator version of it
through the same switches (including refused ones) and compares everything observable.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from types import ModuleType, SimpleNamespace
from typing import Any

from contextros import Layer, activate, active_layers, deactivate, layered, proceed, switch
from contextros.core.runtime import RUNTIME
from contextros.errors import LayerError


def decorator_version() -> SimpleNamespace:
    """fixtures/cleaner.layers, written by hand with the core's decorator API."""
    events: list[str] = []

    @dataclass
    class Cleaner:
        log: list[str] = field(default_factory=list)

        @layered
        def clean(self, area: str) -> str:
            return f"vacuum {area}"

    indoor = Layer(
        "Indoor",
        description="Inside a building: careful and slow.",
        group="location",
        on_activate=lambda: events.append("Indoor on"),
        on_deactivate=lambda: events.append("Indoor off"),
    )
    outdoor = Layer("Outdoor", group="location")
    night = Layer("Night", description="After dark: quiet.")
    docked = Layer("Docked", excludes=("Outdoor", "Night"), requires=("Indoor",))

    @layered
    def speed(factor: float = 1.0) -> float:
        return 1.0 * factor

    @speed.partial(indoor)
    def speed(factor: float = 1.0) -> float:
        return proceed(factor) * 0.5

    @speed.partial(outdoor)
    def speed(factor: float = 1.0) -> float:
        return 2.0 * factor

    @speed.partial(night)
    def speed(factor: float = 1.0) -> float:
        return proceed(factor) / 4

    @Cleaner.clean.partial(indoor)
    def _clean_indoor(self: Cleaner, area: str) -> str:
        return "wipe+" + proceed(self, area)

    @Cleaner.clean.partial(night)
    def _clean_night(self: Cleaner, area: str) -> str:
        return "quietly " + proceed(self, area)

    @Cleaner.clean.partial(docked)
    def _clean_docked(self: Cleaner, area: str) -> str:
        raise RuntimeError(f"docked, cannot clean {area}")

    @layered(base=False)
    async def status() -> str: ...

    @status.partial(docked)
    async def status(self: Any = None) -> str:
        return "charging"

    return SimpleNamespace(Cleaner=Cleaner, speed=speed, status=status, EVENTS=events)


STEPS: list[tuple[str, Callable[[], object]]] = [
    ("nothing active", lambda: None),
    ("activate Indoor", lambda: activate("Indoor")),
    ("activate Night", lambda: activate("Night")),
    ("switch to Outdoor (group)", lambda: activate("Outdoor")),
    ("deactivate Night", lambda: deactivate("Night")),
    ("back Indoor", lambda: activate("Indoor")),
    ("activate Docked", lambda: activate("Docked")),
    ("Outdoor while Docked (refused)", lambda: activate("Outdoor")),
    ("Night while Docked (refused)", lambda: activate("Night")),
    ("undock and leave", lambda: switch(activate=["Outdoor"], deactivate=["Docked"])),
    ("Docked without Indoor (refused)", lambda: activate("Docked")),
    ("deactivate all", lambda: deactivate("Outdoor")),
]


def outcome(call: Callable[[], object]) -> object:
    try:
        return ("ok", call())
    except (LayerError, RuntimeError) as error:
        # Messages name functions by qualified name; the hand-written ones are local.
        return (type(error).__name__, str(error).replace("decorator_version.<locals>.", ""))


def run_scenario(program: Any) -> list[dict[str, object]]:
    RUNTIME.reset()
    observed = []
    robot = program.Cleaner()
    for name, step in STEPS:
        observed.append(
            {
                "step": name,
                "switch": outcome(step),
                "active": [layer.name for layer in active_layers()],
                "speed": outcome(lambda: program.speed(2.0)),
                "clean": outcome(lambda: robot.clean("hall")),
                "status": outcome(lambda: asyncio.run(program.status())),
                "events": list(program.EVENTS),
            }
        )
    return observed


def normalise(rows: list[dict[str, object]]) -> list[dict[str, object]]:
    """Switch results are objects; compare what they say, not their identity."""
    for row in rows:
        kind, value = row["switch"]  # type: ignore[misc]
        if kind == "ok" and value is not None:
            row["switch"] = ("ok", value.applied, value.deferred)
    return rows


def test_compiled_file_and_decorators_agree(load_fixture: Callable[[str], ModuleType]) -> None:
    by_hand = normalise(run_scenario(decorator_version()))
    compiled = normalise(run_scenario(load_fixture("cleaner.layers")))
    assert compiled == by_hand
    # The scenario exercises what it claims to, in both.
    by_step = {row["step"]: row for row in compiled}
    assert by_step["activate Night"]["clean"] == ("ok", "quietly wipe+vacuum hall")
    assert by_step["activate Night"]["speed"] == ("ok", 0.25)
    assert by_step["activate Docked"]["status"] == ("ok", "charging")
    assert by_step["Outdoor while Docked (refused)"]["switch"][0] == "RelationError"  # type: ignore[index]
    assert by_step["switch to Outdoor (group)"]["active"] == ["Night", "Outdoor"]
    assert by_step["deactivate all"]["events"] == [
        "Indoor on",
        "Indoor off",
        "Indoor on",
        "Indoor off",
    ]
