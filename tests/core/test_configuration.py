"""Relations: excludes, requires and exclusive groups, checked before anything changes."""

from __future__ import annotations

import pytest

from contextros import (
    Layer,
    RelationError,
    activate,
    active_layers,
    current_epoch,
    deactivate,
    set_active,
    switch,
)


def names() -> list[str]:
    return [layer.name for layer in active_layers()]


def test_activation_order_is_kept_and_reactivation_is_idempotent() -> None:
    a, b = Layer("A"), Layer("B")
    activate(a)
    activate(b)
    epoch = current_epoch()
    result = activate(a)
    assert names() == ["A", "B"]
    assert result.applied and result.epoch == epoch == current_epoch()


def test_excluded_layers_cannot_be_active_together_and_nothing_changes() -> None:
    Layer("Wet")
    Layer("Dry", excludes=["Wet"])
    activate("Wet")
    epoch = current_epoch()
    with pytest.raises(RelationError, match="Dry and Wet cannot be active together") as caught:
        activate("Dry")
    assert set(caught.value.layers) == {"Dry", "Wet"}
    assert names() == ["Wet"] and current_epoch() == epoch


def test_exclusion_is_symmetric() -> None:
    Layer("Wet")
    Layer("Dry", excludes=["Wet"])
    activate("Dry")
    with pytest.raises(RelationError, match="Dry and Wet"):
        activate("Wet")
    assert names() == ["Dry"]


def test_requires_needs_the_other_layer_active() -> None:
    Layer("Sensors")
    Layer("Mapping", requires=["Sensors"])
    with pytest.raises(RelationError, match="Mapping requires Sensors"):
        activate("Mapping")
    assert names() == []
    activate("Sensors", "Mapping")
    assert names() == ["Sensors", "Mapping"]
    with pytest.raises(RelationError, match="Mapping requires Sensors"):
        deactivate("Sensors")
    assert names() == ["Sensors", "Mapping"]


def test_requires_an_undefined_layer_can_never_activate() -> None:
    Layer("Orphan", requires=["NeverDefined"])
    with pytest.raises(RelationError, match="Orphan requires NeverDefined"):
        activate("Orphan")


def test_exclusive_group_swaps_members_atomically() -> None:
    Layer("Indoor", group="location")
    Layer("Outdoor", group="location")
    Layer("Night")
    activate("Indoor", "Night")
    before = current_epoch()
    activate("Outdoor")
    assert names() == ["Night", "Outdoor"]
    assert current_epoch() == before + 1  # one transition, not two


def test_two_members_of_a_group_in_one_request_are_rejected() -> None:
    Layer("Indoor", group="location")
    Layer("Outdoor", group="location")
    with pytest.raises(RelationError, match="Indoor and Outdoor are both in exclusive group"):
        activate("Indoor", "Outdoor")
    assert names() == []


def test_group_swap_that_breaks_a_requirement_is_rejected_whole() -> None:
    Layer("Indoor", group="location")
    Layer("Outdoor", group="location")
    Layer("Wiping", requires=["Indoor"])
    activate("Indoor", "Wiping")
    with pytest.raises(RelationError, match="Wiping requires Indoor"):
        activate("Outdoor")
    assert names() == ["Indoor", "Wiping"]


def test_switch_validates_the_final_configuration_only() -> None:
    Layer("Sensors")
    Layer("Lidar")
    Layer("Mapping", requires=["Lidar"])
    activate("Sensors")
    switch(activate=["Lidar", "Mapping"], deactivate=["Sensors"])
    assert names() == ["Lidar", "Mapping"]


def test_a_layer_both_activated_and_deactivated_is_an_error() -> None:
    Layer("Flip")
    with pytest.raises(RelationError, match="Flip asked to be both activated and deactivated"):
        switch(activate=["Flip"], deactivate=["Flip"])


def test_set_active_makes_the_configuration_exactly_so_in_order() -> None:
    for name in ("A", "B", "C"):
        Layer(name)
    activate("A", "B")
    set_active(["C", "B"])
    assert names() == ["C", "B"]
    Layer("D", excludes=["C"])
    with pytest.raises(RelationError, match="D and C"):
        set_active(["C", "D"])
    with pytest.raises(RelationError, match="listed twice"):
        set_active(["A", "A"])
    assert names() == ["C", "B"]
