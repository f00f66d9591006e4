"""Partials defined in another module than the layered function (as compiled layer files
refine the classes of a node module) reach the head through a trampoline; it must pass
every kind of parameter on exactly."""

from __future__ import annotations

import textwrap
from typing import Any

import pytest

from contextros import Layer, activate, layered, proceed

Other = Layer("OtherModule")


def from_another_module(source: str) -> Any:
    namespace: dict[str, Any] = {"proceed": proceed}
    exec(compile(textwrap.dedent(source), "<another module>", "exec"), namespace)
    return namespace["partial"]


def test_every_parameter_kind_is_passed_on() -> None:
    @layered
    def f(a, b=2, /, c=3, *rest, d, e=5, **extra):  # type: ignore[no-untyped-def]
        return ("base", a, b, c, rest, d, e, extra)

    f.partial(Other)(
        from_another_module(
            """
            def partial(a, b=2, /, c=3, *rest, d, e=5, **extra):
                return ("other",) + proceed(a, b, c, *rest, d=d, e=e, **extra)
            """
        )
    )
    activate(Other)
    assert f.__code__.co_filename.startswith("<contextros dispatch")
    assert f.__code__.co_argcount == 3  # the exact trampoline: no *args packing
    assert f(1, d=4) == ("other", "base", 1, 2, 3, (), 4, 5, {})
    assert f(1, 9, 8, 7, 6, d=0, e=1, z=2) == ("other", "base", 1, 9, 8, (7, 6), 0, 1, {"z": 2})
    with pytest.raises(TypeError):
        f(1)  # d is required, as in the base signature


def test_partial_with_other_defaults_keeps_its_own_defaults() -> None:
    @layered
    def g(x: int = 1) -> int:
        return x

    g.partial(Other)(from_another_module("def partial(x=100):\n    return x\n"))
    activate(Other)
    assert g.__code__.co_argcount == 0  # the generic trampoline: the partial's defaults apply
    assert g() == 100 and g(5) == 5


def test_partial_with_other_parameter_names_still_gets_positionals() -> None:
    @layered
    def h(x: int, *, scale: int = 1) -> int:
        return x * scale

    h.partial(Other)(
        from_another_module("def partial(y, *, scale=1):\n    return -proceed(y, scale=scale)\n")
    )
    activate(Other)
    assert h(3, scale=2) == -6
