"""What ROS's parameter and lifecycle messages hold, as the plain values layers set and rules
compare: the one table of rcl_interfaces/msg/ParameterValue's types and lifecycle_msgs'
state ids (ROS-free: messages are read by their fields, built by the caller's class).

Used by the rules' graph conditions (`contextros.rules.graph`), the actual state of the
bindings (`contextros.bindings.actual`), the manager's binding driver (`contextros.ros.bindings`)
and the graph observer (`contextros.ros.graph_observer`), live and in recordings alike.
Everything here may come from any process: a value is taken only if it is exactly of its type.
"""

from __future__ import annotations

from typing import Any, cast

from contextros.language.bindings import ParameterValue as Value
from contextros.language.rules import LIFECYCLE_STATES

# rcl_interfaces/msg/ParameterType: the plain kinds, each with its field and Python type.
NOT_SET = 0
BOOL, INTEGER, DOUBLE, STRING = 1, 2, 3, 4
PARAMETER_FIELDS: dict[int, tuple[str, type]] = {
    BOOL: ("bool_value", bool),
    INTEGER: ("integer_value", int),
    DOUBLE: ("double_value", float),
    STRING: ("string_value", str),
}
ARRAY_KINDS = {
    5: "byte array",
    6: "bool array",
    7: "integer array",
    8: "double array",
    9: "string array",
}
# The longest string parameter value taken (a longer one has no value: untrusted).
MAX_STRING = 4096

# lifecycle_msgs/msg/State: every state a node reports (language.rules), the primary ones
# (what a binding sets or finds a node in), and 0, unknown (the node is absent).
UNKNOWN_STATE = 0
PRIMARY_STATES = {i: name for i, name in LIFECYCLE_STATES.items() if i <= 4}
STATE_IDS = {name: i for i, name in LIFECYCLE_STATES.items()}


def plain_value(message: Any) -> tuple[Value | None, str]:
    """A ParameterValue message as a plain value, or (None, why not)."""
    kind = getattr(message, "type", None)
    if kind == NOT_SET:
        return None, "not set (does the node declare it?)"
    if kind in ARRAY_KINDS:
        return None, f"a {ARRAY_KINDS[kind]} (rules compare plain values)"
    if kind not in PARAMETER_FIELDS:
        return None, f"of an unknown parameter type {kind!r}"
    field, python_type = PARAMETER_FIELDS[kind]
    plain: Any = getattr(message, field, None)
    if isinstance(plain, str) and len(plain) > MAX_STRING:
        return None, f"a string of {len(plain)} characters (more than {MAX_STRING})"
    if type(plain) is not python_type:  # (exactly: a bool is not an integer)
        return None, f"malformed (type {kind} with a {type(plain).__name__} value)"
    return cast(Value, plain), ""


def parameter_fields(value: Value | None, like: int = NOT_SET) -> tuple[int, str, Value | None]:
    """(type, field, value) of a ParameterValue holding `value` (None: not set); an integer
    goes to a parameter of type `like` DOUBLE as a double."""
    if value is None:
        return NOT_SET, "", None
    if isinstance(value, bool):
        kind = BOOL
    elif isinstance(value, int) and like != DOUBLE:
        kind = INTEGER
    elif isinstance(value, (int, float)):
        kind, value = DOUBLE, float(value)
    else:
        kind = STRING
    return kind, PARAMETER_FIELDS[kind][0], value


def shown_parameter(message: Any) -> str:
    """A ParameterValue as text, for messages: `true`, `0.3`, `'eco'`, `(not set)`."""
    kind = getattr(message, "type", None)
    plain, _ = plain_value(message)
    if plain is None:
        return "(not set)" if kind == NOT_SET else f"(type {kind})"
    if isinstance(plain, bool):
        return "true" if plain else "false"
    if isinstance(plain, float):
        return f"{plain:g}"
    return repr(plain) if isinstance(plain, str) else str(plain)


def to_json(message: Any) -> dict[str, Any]:
    """A ParameterValue as JSON (a type no binding sets is kept as not set)."""
    plain, _ = plain_value(message)
    if plain is None:
        return {"type": NOT_SET, "value": None}
    return {"type": message.type, "value": plain}


def from_json(data: Any) -> tuple[int, str, Value | None]:
    """(type, field, value) of a ParameterValue written by `to_json`; ValueError if not one."""
    kind = data["type"]
    if kind == NOT_SET:
        return NOT_SET, "", None
    if kind not in PARAMETER_FIELDS:
        raise ValueError(f"unknown parameter type {kind!r}")
    field, python_type = PARAMETER_FIELDS[kind]
    value: Any = data["value"]
    if python_type is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if type(value) is not python_type:
        raise ValueError(f"parameter value {value!r} is not of type {kind}")
    return kind, field, cast(Value, value)


def lifecycle_state(state_id: object) -> str | None:
    """A lifecycle_msgs/msg/State id's name (None: unknown, or not a state id)."""
    return LIFECYCLE_STATES.get(state_id) if type(state_id) is int else None
