"""The one table of ROS parameter values and lifecycle states (ROS-free): what rules,
bindings, drift and recordings take from a ParameterValue message, and write into one."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from contextros.bindings.values import (
    DOUBLE,
    INTEGER,
    NOT_SET,
    PRIMARY_STATES,
    from_json,
    lifecycle_state,
    parameter_fields,
    plain_value,
    shown_parameter,
    to_json,
)


def message(kind: int, **value: object) -> SimpleNamespace:
    fields = {"bool_value": False, "integer_value": 0, "double_value": 0.0, "string_value": ""}
    return SimpleNamespace(type=kind, **{**fields, **value})


@pytest.mark.parametrize(
    ("value", "plain", "shown"),
    [
        (message(1, bool_value=True), True, "true"),
        (message(2, integer_value=3), 3, "3"),
        (message(3, double_value=0.5), 0.5, "0.5"),
        (message(4, string_value="eco"), "eco", "'eco'"),
        (message(0), None, "(not set)"),
        (message(8), None, "(type 8)"),
        (message(2, integer_value=True), None, "(type 2)"),  # a bool is not an integer
        (message(4, string_value="x" * 4097), None, "(type 4)"),
    ],
)
def test_a_parameter_value_is_taken_only_exactly_of_its_type(
    value: SimpleNamespace, plain: object, shown: str
) -> None:
    assert plain_value(value)[0] == plain and type(plain_value(value)[0]) is type(plain)
    assert shown_parameter(value) == shown
    if plain is not None:
        kind, field, written = parameter_fields(plain, like=value.type)  # type: ignore[arg-type]
        assert (kind, getattr(message(kind, **{field: written}), field)) == (value.type, plain)
        assert from_json(to_json(value)) == (kind, field, plain)
    else:
        assert to_json(value) == {"type": NOT_SET, "value": None}


def test_an_integer_goes_to_a_double_parameter_as_a_double() -> None:
    assert parameter_fields(3) == (INTEGER, "integer_value", 3)
    assert parameter_fields(3, like=DOUBLE) == (DOUBLE, "double_value", 3.0)
    assert parameter_fields(None) == (NOT_SET, "", None)
    assert from_json({"type": DOUBLE, "value": 2}) == (DOUBLE, "double_value", 2.0)
    with pytest.raises(ValueError, match="is not of type 2"):
        from_json({"type": INTEGER, "value": "2"})
    with pytest.raises(ValueError, match="unknown parameter type 9"):
        from_json({"type": 9, "value": []})


def test_lifecycle_states_by_id() -> None:
    assert PRIMARY_STATES == {1: "unconfigured", 2: "inactive", 3: "active", 4: "finalized"}
    assert (lifecycle_state(14), lifecycle_state(0), lifecycle_state(True)) == (
        "deactivating",
        None,
        None,
    )
