"""Per-object and class-wide activation (ContextJS / ServalCJ style), composed with
decisive and scoped activation in the documented order."""

from __future__ import annotations

import gc
import threading

import pytest

from contextros import (
    Layer,
    LayerDefinitionError,
    RelationError,
    activate,
    activate_for,
    activated,
    deactivate_for,
    deactivated,
    layered,
    layers_for,
    proceed,
    reset_for,
)

Loud, Slow, Shiny, Dusk = Layer("Loud"), Layer("Slow"), Layer("Shiny"), Layer("Dusk")


class Robot:
    @layered
    def greet(self) -> str:
        return "hello"

    @greet.partial(Loud)
    def greet(self) -> str:
        return proceed(self).upper()

    @greet.partial(Slow)
    def greet(self) -> str:
        return "..." + proceed(self)

    @greet.partial(Shiny)
    def greet(self) -> str:
        return "*" + proceed(self) + "*"

    @layered
    @classmethod
    def kind(cls) -> str:
        return cls.__name__

    @kind.partial(Loud)
    @classmethod
    def kind(cls) -> str:
        return proceed(cls).upper()


class Rover(Robot):
    @layered
    def greet(self) -> str:
        return "rover:" + super().greet()

    @greet.partial(Dusk)
    def greet(self) -> str:
        return proceed(self) + " (quietly)"


class Unrelated:
    @layered
    def greet(self) -> str:
        return "plain"

    @greet.partial(Loud)
    def greet(self) -> str:
        return "PLAIN"


def names(configuration: tuple[Layer, ...]) -> list[str]:
    return [layer.name for layer in configuration]


def test_a_layer_active_for_one_object_only() -> None:
    a, b = Robot(), Robot()
    assert names(activate_for(a, Loud)) == ["Loud"]
    assert (a.greet(), b.greet()) == ("HELLO", "hello")
    reset_for(a)
    assert a.greet() == "hello"


def test_class_wide_activation_reaches_instances_subclasses_and_classmethods() -> None:
    robot, rover, other = Robot(), Rover(), Unrelated()
    activate_for(Robot, Loud)
    assert robot.greet() == "HELLO"
    assert rover.greet() == "rover:HELLO"  # Rover is a Robot: super() sees Loud too
    assert Robot.kind() == "ROBOT" and Rover.kind() == "ROVER"
    assert other.greet() == "plain"  # another class: untouched
    reset_for(Robot)
    assert robot.greet() == "hello" and Robot.kind() == "Robot"


def test_the_documented_order_decisive_class_object_scope() -> None:
    robot = Robot()
    activate(Slow)  # decisive: innermost
    activate_for(Robot, Shiny)  # class-wide: next
    activate_for(robot, Loud)  # per object: next
    assert names(layers_for(robot)) == ["Slow", "Shiny", "Loud"]
    assert robot.greet() == "*...HELLO*"  # Loud(Shiny(Slow(base)))
    with activated(Dusk):  # the caller's scope comes last
        assert names(layers_for(robot)) == ["Slow", "Shiny", "Loud", "Dusk"]
    with deactivated(Loud):  # and has the last word
        assert robot.greet() == "*...hello*"


def test_an_object_can_opt_out_of_a_decisive_layer() -> None:
    a, b = Robot(), Robot()
    activate(Loud)
    deactivate_for(a, Loud)
    assert (a.greet(), b.greet()) == ("hello", "HELLO")
    activate_for(a, Loud)  # a later step for the same layer replaces the earlier one
    assert a.greet() == "HELLO"


def test_decisive_switches_show_through_per_object_layers() -> None:
    robot = Robot()
    activate_for(robot, Loud)
    assert robot.greet() == "HELLO"
    activate(Shiny)
    assert robot.greet() == "*HELLO*"  # Shiny older than the object's Loud


def test_relations_are_checked_for_the_target() -> None:
    Layer("Grip", requires=["Arm"])
    robot = Robot()
    with pytest.raises(RelationError, match="Grip requires Arm"):
        activate_for(robot, "Grip")
    assert names(layers_for(robot)) == []


def test_classes_without_receiver_layers_keep_the_direct_path() -> None:
    direct = Unrelated.greet.__code__
    robot = Robot()
    activate_for(robot, Loud)
    assert Unrelated.greet.__code__ is direct
    assert Robot.greet.__code__ is not direct
    reset_for(robot)
    assert Robot.greet.__code__.co_filename == __file__  # back to the direct path


def test_per_object_layers_go_with_the_object() -> None:
    robot = Robot()
    activate_for(robot, Loud)
    del robot
    gc.collect()
    assert Robot().greet() == "hello"
    assert Robot.greet.__code__.co_filename == __file__


def test_objects_without_weak_references_are_refused_with_advice() -> None:
    class Slotted(Robot):
        __slots__ = ()

    class Tight:
        __slots__ = ("x",)

    with pytest.raises(LayerDefinitionError, match="weak references"):
        activate_for(Tight(), Loud)


def test_other_threads_see_per_object_layers_at_their_next_call() -> None:
    robot = Robot()
    seen: list[str] = []
    activate_for(robot, Loud)
    thread = threading.Thread(target=lambda: seen.append(robot.greet()))
    thread.start()
    thread.join(5)
    assert seen == ["HELLO"]
