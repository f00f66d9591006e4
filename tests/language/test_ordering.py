"""`after` made real: activation_order sorts layers so the declared orders hold."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import pytest

from contextros import set_active
from contextros.errors import RelationError
from contextros.language import activation_order


def test_declared_orders_decide_which_partial_is_outermost(
    load_fixture: Callable[[str], ModuleType],
) -> None:
    module = load_fixture("cleaner.layers")
    # Night is declared `after Indoor`: asked in the wrong order, it still ends up outermost.
    order = activation_order(module, ["Night", module.Indoor])
    assert order == ["Indoor", "Night"]
    set_active(order)
    assert module.Cleaner().clean("hall") == "quietly wipe+vacuum hall"


def test_unrelated_layers_keep_the_given_order(load_fixture: Callable[[str], ModuleType]) -> None:
    module = load_fixture("cleaner.layers")
    assert activation_order(module, ["Docked", "Indoor"]) == ["Indoor", "Docked"]
    assert activation_order(module, ["Outdoor", "Docked"]) == ["Outdoor", "Docked"]


def test_a_cycle_is_refused() -> None:
    module = ModuleType("fake")
    module.__layer_order__ = (("A", "B"), ("B", "A"))  # type: ignore[attr-defined]
    with pytest.raises(RelationError):
        activation_order(module, ["A", "B"])
    with pytest.raises(TypeError):
        activation_order(module, [1])
