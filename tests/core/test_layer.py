from __future__ import annotations

import pytest

from contextros import Layer, LayerDefinitionError, UnknownLayerError, layer_named


def test_layers_are_values_named_and_hashable() -> None:
    a, b = Layer("Indoor"), Layer("Indoor")
    assert a == b and hash(a) == hash(b)
    assert {a, b, Layer("Outdoor")} == {Layer("Indoor"), Layer("Outdoor")}
    assert repr(a) == "Layer('Indoor')" and str(a) == "Indoor"


def test_relations_are_stored_as_names() -> None:
    sensors = Layer("Sensors")
    night = Layer("Night", excludes=["Day"], requires=sensors, group="light", description="dark")
    assert night.excludes == frozenset({"Day"})
    assert night.requires == frozenset({"Sensors"})
    assert night.group == "light" and night.description == "dark"


def test_latest_definition_of_a_name_is_registered() -> None:
    Layer("Redefined", group="g1")
    Layer("Redefined", group="g2")
    assert layer_named("Redefined").group == "g2"


def test_unknown_layer_error_names_the_layer_and_the_known_ones() -> None:
    Layer("KnownOne")
    with pytest.raises(UnknownLayerError, match=r"unknown layer 'Nope'.*KnownOne"):
        layer_named("Nope")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "not an identifier"}, "not an identifier"),
        ({"name": "Self", "excludes": ["Self"]}, "cannot exclude itself"),
        ({"name": "Both", "excludes": ["X"], "requires": ["X"]}, "both requires and excludes X"),
        ({"name": "Hooked", "on_activate": 3}, "on_activate is not callable"),
        ({"name": "Grouped", "group": "two words"}, "group 'two words' is not an identifier"),
        ({"name": "Rel", "requires": [3]}, "require names 3"),
    ],
)
def test_bad_definitions_are_rejected_with_the_reason(kwargs: dict, message: str) -> None:
    with pytest.raises(LayerDefinitionError, match=message):
        Layer(**kwargs)


def test_defined_layers_lists_current_definitions() -> None:
    from contextros import defined_layers

    Layer("Listed", group="first")
    Layer("Listed", group="second")
    listed = [layer for layer in defined_layers() if layer.name == "Listed"]
    assert len(listed) == 1 and listed[0].group == "second"
