"""Message definitions as rosbag2 stores them in MCAP schemas (encoding `ros2msg`): the
type's .msg text, then each type it uses, after a line of 80 '=' and `MSG: pkg/Name`.

The .msg files come from the `share/<pkg>/msg/` directory of the installed packages (the
ROS 2 wheels and a system ROS 2 both install them); the types a message uses come from its
Python class (`get_fields_and_field_types`), so no .msg parser is needed here.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from pathlib import Path
from typing import Any

SEPARATOR = "=" * 80
_NESTED = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)/([A-Za-z_][A-Za-z0-9_]*)")


class DefinitionError(Exception):
    """A message type whose definition cannot be found here."""


def message_definition(type_name: str) -> str:
    """The full definition of `type_name` ('sensor_msgs/msg/BatteryState')."""
    package, name = _split(type_name)
    parts = [_msg_text(package, name).rstrip("\n")]
    seen = {(package, name)}
    pending = _used_types(package, name)
    while pending:
        used = pending.pop(0)
        if used in seen:
            continue
        seen.add(used)
        parts.append(f"{SEPARATOR}\nMSG: {used[0]}/{used[1]}\n{_msg_text(*used).rstrip(chr(10))}")
        pending += _used_types(*used)
    return "\n".join(parts) + "\n"


def _split(type_name: str) -> tuple[str, str]:
    pieces = type_name.split("/")
    if len(pieces) == 3 and pieces[1] == "msg":
        return pieces[0], pieces[2]
    if len(pieces) == 2:
        return pieces[0], pieces[1]
    raise DefinitionError(f"{type_name!r} is not a message type name (pkg/msg/Name)")


def _used_types(package: str, name: str) -> list[tuple[str, str]]:
    try:
        cls = getattr(importlib.import_module(f"{package}.msg"), name)
        fields: dict[str, str] = cls.get_fields_and_field_types()
    except (ImportError, AttributeError) as error:
        raise DefinitionError(f"message {package}/msg/{name} is not installed: {error}") from None
    return [(m.group(1), m.group(2)) for t in fields.values() if (m := _NESTED.search(t))]


def _msg_text(package: str, name: str) -> str:
    for share in _share_directories():
        path = share / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise DefinitionError(
        f"no {package}/msg/{name}.msg in the installed packages' share directories "
        "(AMENT_PREFIX_PATH, the Python environment)"
    )


def _share_directories() -> list[Path]:
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes += [sys.prefix, sys.base_prefix]
    return [Path(prefix) / "share" for prefix in dict.fromkeys(prefixes)]


def type_of(message: Any) -> str:
    """The type name of a message object ('sensor_msgs/msg/BatteryState')."""
    cls = type(message)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"
