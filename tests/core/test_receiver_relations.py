"""Relations across receivers: a class-wide change is validated for every receiver it
affects (subclasses, objects with layers of their own); a decisive switch is never refused
for a receiver, it suspends the receiver's levels that break a relation with it."""

from __future__ import annotations

import logging

import pytest

from contextros import (
    Layer,
    RelationError,
    activate,
    activate_for,
    deactivate,
    layered,
    layers_for,
    proceed,
    reset_for,
)

Near = Layer("RelNear")
Far = Layer("RelFar", excludes="RelNear")
Extra = Layer("RelExtra")


class Robot:
    def __repr__(self) -> str:
        return "<the robot>"

    @layered
    def speed(self) -> int:
        return 1

    @speed.partial(Near)
    def speed(self) -> int:
        return proceed(self) * 10

    @speed.partial(Far)
    def speed(self) -> int:
        return proceed(self) + 5

    @speed.partial(Extra)
    def speed(self) -> int:
        return proceed(self) + 100


class Rover(Robot):
    pass


def test_a_class_wide_change_breaking_an_object_s_layers_is_refused_naming_it() -> None:
    r = Robot()
    activate_for(r, Near)
    with pytest.raises(RelationError) as raised:
        activate_for(Robot, Far)
    message = str(raised.value)
    assert "RelFar" in message and "RelNear" in message and "excludes" in message
    assert "<the robot>" in message and "class Robot" in message
    assert set(raised.value.layers) == {"RelFar", "RelNear"}
    assert layers_for(r) == (Near,)
    assert layers_for(Robot) == ()
    assert (r.speed(), Robot().speed()) == (10, 1)


def test_a_class_wide_change_breaking_a_subclass_s_layers_is_refused_naming_it() -> None:
    activate_for(Rover, Near)
    with pytest.raises(RelationError, match=r"RelFar.*RelNear.*class .*Rover"):
        activate_for(Robot, Far)
    assert layers_for(Rover) == (Near,)
    assert layers_for(Robot) == ()
    reset_for(Rover)
    rover_object = Rover()  # an object of a subclass, with layers of its own
    activate_for(rover_object, Near)
    with pytest.raises(
        RelationError, match=r"object <the robot>.*class-wide layers of class Robot"
    ):
        activate_for(Robot, Far)
    assert layers_for(rover_object) == (Near,)


def test_a_decisive_switch_suspends_the_receiver_levels_it_conflicts_with(
    caplog: pytest.LogCaptureFixture,
) -> None:
    r = Robot()
    activate_for(r, Near)
    with caplog.at_level(logging.WARNING, logger="contextros"):
        assert activate(Far).applied  # never refused for a receiver
    assert layers_for(r) == (Far,)  # the decisive configuration wins
    assert r.speed() == 6
    assert "own layers of object <the robot> suspended" in caplog.text
    with pytest.raises(RelationError, match="<the robot>"):
        activate_for(r, Extra)  # would add to a suspended level: refused
    assert layers_for(r) == (Far,)
    reset_for(r, Near)  # forgetting is allowed
    activate_for(r, Extra)
    assert layers_for(r) == (Far, Extra)
    deactivate(Far)
    assert layers_for(r) == (Extra,)


def test_a_suspended_level_applies_again_once_the_conflict_is_gone() -> None:
    r = Robot()
    activate_for(r, Near)
    activate_for(Rover, Near)
    activate(Far)
    assert (layers_for(r), layers_for(Rover)) == ((Far,), (Far,))
    assert (r.speed(), Rover().speed()) == (6, 6)
    deactivate(Far)
    assert (layers_for(r), layers_for(Rover)) == ((Near,), (Near,))
    assert (r.speed(), Rover().speed()) == (10, 10)


def test_no_implementation_names_the_layers_the_receiver_saw() -> None:
    from contextros import NoImplementationError, deactivate_for

    class Sensor:
        @layered(base=False)
        def read(self) -> int: ...

        @read.partial(Near)
        def read(self) -> int:
            return 7

    s = Sensor()
    activate(Near)
    deactivate_for(s, Near)
    activate_for(s, Extra)
    assert Sensor().read() == 7
    with pytest.raises(NoImplementationError, match=r"active layers: RelExtra\)"):
        s.read()
