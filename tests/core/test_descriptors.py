"""Layered classmethods, staticmethods and properties, with inheritance and super()."""

from __future__ import annotations

import pytest

from contextros import Layer, LayerDefinitionError, activate, activated, layered, proceed
from contextros.core import LayeredProperty, layered_function_of

Fast, Quiet = Layer("Fast"), Layer("Quiet")


class Robot:
    made: list[str] = []

    @layered
    @classmethod
    def create(cls, name: str) -> str:
        return f"{cls.__name__}({name})"

    @create.partial(Fast)
    @classmethod
    def create(cls, name: str) -> str:
        return "fast " + proceed(cls, name)

    @layered
    @staticmethod
    def limit(x: int) -> int:
        return x

    @limit.partial(Quiet)
    @staticmethod
    def limit(x: int) -> int:
        return min(proceed(x), 3)

    @layered
    @property
    def speed(self) -> float:
        return 1.0

    @speed.partial(Fast)
    def speed(self) -> float:
        return proceed(self) * 2

    @speed.setter
    def speed(self, value: float) -> None:
        self.set_to = value


class Drone(Robot):
    @layered
    @classmethod
    def create(cls, name: str) -> str:
        return "drone:" + super().create(name)

    @create.partial(Quiet)
    @classmethod
    def create(cls, name: str) -> str:
        return "quiet " + proceed(cls, name)

    @layered
    @property
    def speed(self) -> float:
        return super().speed + 10

    @speed.partial(Quiet)
    def speed(self) -> float:
        return proceed(self) / 2


def test_classmethods_dispatch_on_the_class_and_its_subclasses() -> None:
    assert Robot.create("r") == "Robot(r)"
    activate(Fast)
    assert Robot.create("r") == "fast Robot(r)"
    assert Robot().create("r") == "fast Robot(r)"
    assert isinstance(Robot.__dict__["create"], classmethod)
    assert layered_function_of(Robot.__dict__["create"]) is not None


def test_a_subclass_classmethod_with_super_composes_both_chains() -> None:
    assert Drone.create("d") == "drone:Drone(d)"
    activate(Fast, Quiet)
    assert Drone.create("d") == "quiet drone:fast Drone(d)"


def test_staticmethods_dispatch_without_an_instance() -> None:
    assert Robot.limit(10) == 10
    with activated(Quiet):
        assert Robot.limit(10) == 3 and Robot().limit(10) == 3
    assert isinstance(Robot.__dict__["limit"], staticmethod)


def test_properties_layer_their_getter_and_keep_their_setter() -> None:
    robot = Robot()
    assert robot.speed == 1.0
    activate(Fast)
    assert robot.speed == 2.0
    robot.speed = 5.0
    assert robot.set_to == 5.0  # type: ignore[attr-defined]
    assert isinstance(Robot.__dict__["speed"], LayeredProperty)


def test_property_inheritance_with_super() -> None:
    drone = Drone()
    assert drone.speed == 11.0
    activate(Fast, Quiet)
    assert drone.speed == 6.0  # Quiet(Drone: super() -> Fast(Robot base) + 10)


def test_a_property_without_getter_is_refused() -> None:
    with pytest.raises(LayerDefinitionError, match="getter"):
        layered(property())  # type: ignore[call-overload]
