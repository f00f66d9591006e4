"""Message types by name, from the interfaces installed in this Python environment.

What the Layer manager checks a rule's fields with, once the ROS graph names a topic's type,
and what `contextros check` checks them with offline, from a `topic` declaration: one lookup,
so both report the same errors. Imports message packages (`pkg.msg`), never rclpy.
"""

from __future__ import annotations

import difflib
import importlib
import re
from typing import Any

from contextros.rules.ruleset import FieldKind, FieldLookup, NoSuchMessageType

_TYPE_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/msg/([A-Za-z_][A-Za-z0-9_]*)$")
_NESTED = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/([A-Za-z_][A-Za-z0-9_]*)$")
# A byte (IDL octet) arrives from rclpy as `bytes` of length 1: the engine compares its number.
# A char (IDL char/wchar) arrives as a one-character `str`.
_NUMBERS = {
    "octet",
    "byte",
    "float",
    "double",
    "long double",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
}
_CHARACTERS = {"char", "wchar"}


def message_class(type_name: str) -> Any:
    """The Python class of a message type named by the graph ('sensor_msgs/msg/NavSatFix').
    The name comes from the network: only the `pkg/msg/Name` form is imported, from
    `pkg.msg`; anything else is a ValueError naming it."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(f"{type_name!r} is not a message type name (pkg/msg/Name)")
    package, name = match.groups()
    try:
        module = importlib.import_module(f"{package}.msg")
    except ImportError as error:
        raise ValueError(f"message package {package!r} is not installed here: {error}") from error
    cls = getattr(module, name, None)
    if cls is None or not hasattr(cls, "get_fields_and_field_types"):
        types = [n for n, v in vars(module).items() if hasattr(v, "get_fields_and_field_types")]
        close = difflib.get_close_matches(name, types, n=3)
        hint = f" (did you mean {' or '.join(close)}?)" if close else ""
        raise NoSuchMessageType(f"{package}.msg has no message type {name!r}{hint}")
    return cls


def field_kind(cls: Any, path: tuple[str, ...]) -> FieldKind:
    """What `path` is in message class `cls`: number, string, bool, message, array or None."""
    kind: str | None = None
    for index, name in enumerate(path):
        fields: dict[str, str] = cls.get_fields_and_field_types()
        ros_type = fields.get(name)
        if ros_type is None:
            return None
        if ros_type.startswith("sequence<") or "[" in ros_type:
            kind = "array"
        elif ros_type == "boolean":
            kind = "bool"
        elif ros_type in _NUMBERS:
            kind = "number"
        elif ros_type in _CHARACTERS or ros_type.startswith(("string", "wstring")):
            kind = "string"
        elif nested := _NESTED.match(ros_type):
            kind = "message"
            cls = message_class(f"{nested.group(1)}/msg/{nested.group(2)}")
        else:
            kind = "array"  # anything else is not comparable
        if kind != "message" and index < len(path) - 1:
            return None  # a plain value has no fields
    return kind


def installed_message_type(type_name: str) -> FieldLookup:
    """The field lookup of message type `type_name` (PACKAGE/msg/NAME) as installed here; a
    ValueError says why it is not (`contextros.rules.ruleset.MessageTypes`)."""
    cls = message_class(type_name)

    def lookup(path: tuple[str, ...]) -> FieldKind:
        return field_kind(cls, path)

    return lookup
