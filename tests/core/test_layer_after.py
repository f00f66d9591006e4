"""`Layer(after=...)`: the declared composition order travels with the layer."""

from __future__ import annotations

import pytest

from contextros.core import Layer
from contextros.errors import LayerDefinitionError


def test_after_names_are_kept_as_a_set_of_names() -> None:
    flooded = Layer("Flooded")
    assert Layer("Rubble", after=[flooded, "Dusty"]).after == frozenset({"Flooded", "Dusty"})
    assert Layer("Flight").after == frozenset()


def test_a_layer_cannot_come_after_itself_or_a_non_name() -> None:
    with pytest.raises(LayerDefinitionError, match="cannot come after itself"):
        Layer("Rubble", after=["Rubble"])
    with pytest.raises(LayerDefinitionError, match="not a layer or a layer name"):
        Layer("Rubble", after=["two words"])
