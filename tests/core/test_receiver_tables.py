"""The tables the per-receiver path reads stay the ones the runtime changes: after every
per-object or class-wide change, partial added or removed, layer removed, decisive switch."""

from __future__ import annotations

import gc

from contextros import Layer, activate_for, layered, layers_for, proceed, reset_for
from contextros.core.layered import layered_function_of

A = Layer("TablesA")


def _robot_class() -> type:
    class Robot:
        __slots__ = ("__weakref__",)

        @layered
        def speed(self) -> int:
            return 1

        @speed.partial(A)
        def speed(self) -> int:
            return proceed(self) * 10

    return Robot


def _installed_objects(function: object) -> dict[int, object]:
    owner = layered_function_of(function)
    assert owner is not None
    table = owner.installed_objects()
    assert table is not None
    return table


def test_reset_for_one_object_while_another_keeps_its_layers() -> None:
    Robot = _robot_class()
    r, o = Robot(), Robot()
    activate_for(r, A)
    activate_for(o, A)
    assert (r.speed(), o.speed()) == (10, 10)
    reset_for(r)
    assert layers_for(r) == ()
    assert r.speed() == 1
    assert o.speed() == 10


def test_forgetting_the_last_step_of_one_object_while_another_keeps_its_layers() -> None:
    Robot = _robot_class()
    r, o = Robot(), Robot()
    activate_for(r, A)
    activate_for(o, A)
    reset_for(r, A)
    assert r.speed() == 1
    assert o.speed() == 10


def test_a_gone_object_leaves_the_installed_table_and_its_id_carries_no_layers() -> None:
    Robot = _robot_class()
    a, b, keep = Robot(), Robot(), Robot()
    for each in (a, b, keep):
        activate_for(each, A)
    reset_for(b)
    gone = id(a)
    del a
    gc.collect()
    assert gone not in _installed_objects(Robot.speed)
    for _ in range(1000):  # an object reusing the id (CPython usually reuses it at once)
        fresh = Robot()
        if id(fresh) == gone:
            assert layers_for(fresh) == ()
            assert fresh.speed() == 1
            break
        del fresh
    assert keep.speed() == 10


def test_a_partial_added_or_removed_later_is_followed_by_a_receiver_with_layers() -> None:
    class Robot:
        @layered
        def speed(self) -> int:
            return 1

    r = Robot()
    activate_for(r, A)
    assert r.speed() == 1  # composes and caches r's chain: the base only

    @Robot.speed.partial(A)
    def speed(self: Robot) -> int:
        return proceed(self) * 10

    assert r.speed() == 10
    Robot.speed.remove_partial(A)  # type: ignore[attr-defined]
    assert r.speed() == 1


def test_remove_layer_rewires_calls_on_a_receiver_with_that_layer() -> None:
    from contextros import remove_layer

    Doomed = Layer("TablesDoomed")

    class Robot:
        @layered
        def speed(self) -> int:
            return 1

        @speed.partial(Doomed)
        def speed(self) -> int:
            return proceed(self) * 10

    r, whole = Robot(), Robot()
    activate_for(r, Doomed)
    activate_for(Robot, Doomed)
    assert (r.speed(), whole.speed(), Robot().speed()) == (10, 10, 10)
    assert remove_layer(Doomed) == (
        test_remove_layer_rewires_calls_on_a_receiver_with_that_layer.__qualname__
        + ".<locals>.Robot.speed",
    )
    assert (r.speed(), whole.speed(), Robot().speed()) == (1, 1, 1)


def test_layers_for_follows_decisive_switches_without_layered_methods() -> None:
    from contextros import activate

    Later = Layer("TablesLater")

    class Plain:
        pass

    o = Plain()
    activate_for(o, A)
    activate(Later)
    assert layers_for(o) == (Later, A)
    activate_for(Plain, A)
    assert layers_for(Plain) == (Later, A)


def test_forgetting_an_object_s_layers_detaches_its_finalizer() -> None:
    import weakref

    Robot = _robot_class()
    o = Robot()
    registered = len(weakref.finalize._registry)  # type: ignore[attr-defined]
    for _ in range(5):
        activate_for(o, A)
        reset_for(o)
    assert len(weakref.finalize._registry) == registered  # type: ignore[attr-defined]
    activate_for(o, A)
    assert o.speed() == 10
