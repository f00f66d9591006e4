"""Layers that drive ROS: `parameter` and `lifecycle` declarations of layer files.

    parameter LowBattery: /base max_speed = 0.3
    lifecycle Flight: propeller_driver active, wheel_driver inactive
    parameter Slow: /base max_speed = 0.3 on drift restore

While LowBattery is active, node `/base` has its parameter `max_speed` at 0.3 (its previous
value comes back when LowBattery is deactivated); while Flight is active, the lifecycle node
`propeller_driver` is active and `wheel_driver` inactive. Node names are ROS node names,
relative ones resolved in the Layer manager's namespace. The node, the parameter and the
value are written as the `ros2 param set NODE NAME VALUE` command takes them.

`on drift POLICY` after a binding (a parameter line, or one `NODE STATE` item) says what the
manager does when, while the binding is in force, the node no longer has its value or state
(someone else changed it): `report` (the default: status, watch and the dashboard show it),
`restore` (set it back) or `infer` (switch to the layer whose bindings match what is seen).

Like rules, these lines hold no code of the host language: this grammar and its tree are
shared by both flavours (each parser hands over the text after `parameter LAYER:` /
`lifecycle LAYER:`). The Layer manager applies them (`contextros.ros.bindings`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from contextros.language.diagnostics import DiagnosticSink
from contextros.language.literals import string_literal
from contextros.language.positions import Position, Ref

LIFECYCLE_STATES = ("active", "inactive")
DRIFT_POLICIES = ("report", "restore", "infer")
_NODE = r"(?:~/|/)?[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*"
_PARAMETER_NAME = r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*"
_PARAMETER = re.compile(
    rf"""[ \t]*(?P<node>{_NODE})[ \t]+(?P<name>{_PARAMETER_NAME})[ \t]*=[ \t]*
    (?P<value>"(?:[^"\\]|\\.)*"|'(?:[^'\\]|\\.)*'|[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?
    |true|false)(?P<rest>(?:[ \t]+[^\#\s][^\#]*?)?)[ \t]*(?:\#.*)?$""",
    re.VERBOSE,
)
_LIFECYCLE_ITEM = re.compile(
    rf"[ \t]*(?P<node>{_NODE})[ \t]+(?P<state>[A-Za-z_]+)(?P<rest>(?:[ \t]+[^ \t]+)*)[ \t]*"
)
_DRIFT = re.compile(r"[ \t]*on[ \t]+drift[ \t]+(?P<policy>[A-Za-z_]+)[ \t]*$")

ParameterValue = bool | int | float | str


@dataclass(frozen=True)
class ParameterBinding:
    """`parameter LAYER: NODE NAME = VALUE`."""

    layer: Ref
    node: str
    name: str
    value: ParameterValue
    at: Position
    path: str = "<layers>"
    policy: str = "report"  # on drift: one of DRIFT_POLICIES

    def __post_init__(self) -> None:
        _check_policy(self.policy)


@dataclass(frozen=True)
class LifecycleBinding:
    """One `NODE STATE` of `lifecycle LAYER: NODE STATE, ...`."""

    layer: Ref
    node: str
    state: str  # "active" | "inactive"
    at: Position
    path: str = "<layers>"
    policy: str = "report"  # on drift: one of DRIFT_POLICIES

    def __post_init__(self) -> None:
        _check_policy(self.policy)


_POLICIES_SHOWN = f"{', '.join(DRIFT_POLICIES[:-1])} or {DRIFT_POLICIES[-1]}"


def _check_policy(policy: str) -> None:
    if policy not in DRIFT_POLICIES:
        raise ValueError(f"drift policy {policy!r}: expected {_POLICIES_SHOWN}")


def _drift_policy(rest: str, line: int, col: int, sink: DiagnosticSink) -> str | None:
    """The policy of `rest`, what follows a binding (at `col`): "" or `on drift POLICY`;
    None (reported) for anything else."""
    if not rest.strip():
        return "report"
    start = col + len(rest) - len(rest.lstrip(" \t"))
    match = _DRIFT.match(rest)
    if match is None:
        sink.error(
            f"unexpected {rest.strip()!r} after the binding: expected 'on drift POLICY' "
            f"(POLICY {_POLICIES_SHOWN}) or the end of the line",
            line,
            start,
        )
        return None
    policy = match.group("policy")
    if policy not in DRIFT_POLICIES:
        sink.error(
            f"drift policy {policy!r}: expected {_POLICIES_SHOWN}",
            line,
            col + match.start("policy"),
        )
        return None
    return policy


def _value(text: str, line: int, col: int, sink: DiagnosticSink) -> ParameterValue | None:
    """The value written `text` at `line`:`col`; None (reported) for a malformed string."""
    if text in ("true", "false"):
        return text == "true"
    if text[0] in "\"'":
        return string_literal(text, line, col, sink)
    if re.fullmatch(r"[-+]?\d+", text):
        return int(text)
    return float(text)


def parse_parameter(
    layer: Ref, text: str, line: int, col: int, sink: DiagnosticSink
) -> ParameterBinding | None:
    """The text after `parameter LAYER:` (starting at `line`:`col`)."""
    match = _PARAMETER.match(text)
    if match is None:
        sink.error(
            "expected 'NODE PARAMETER = VALUE' (e.g. '/base max_speed = 0.3'; the value a "
            "number, a quoted string, true or false), optionally followed by 'on drift POLICY'",
            line,
            col + len(text) - len(text.lstrip(" \t")),
        )
        return None
    value = _value(match.group("value"), line, col + match.start("value"), sink)
    if value is None:
        return None
    if isinstance(value, float) and not math.isfinite(value):
        sink.error("the value must be a finite number", line, col + match.start("value"))
        return None
    policy = _drift_policy(match.group("rest"), line, col + match.start("rest"), sink)
    if policy is None:
        return None
    return ParameterBinding(
        layer,
        match.group("node"),
        match.group("name"),
        value,
        Position(line, col + match.start("node")),
        sink.path,
        policy,
    )


def parse_lifecycle(
    layer: Ref, text: str, line: int, col: int, sink: DiagnosticSink
) -> list[LifecycleBinding]:
    """The text after `lifecycle LAYER:`: `NODE STATE` items separated by commas."""
    body = text.split("#", 1)[0]
    found: list[LifecycleBinding] = []
    offset = 0
    for item in body.split(","):
        match = _LIFECYCLE_ITEM.fullmatch(item)
        start = col + offset + len(item) - len(item.lstrip(" \t"))
        if match is None:
            sink.error(
                "expected 'NODE active' or 'NODE inactive' (items separated by commas, each "
                "optionally followed by 'on drift POLICY')",
                line,
                start,
            )
            return []
        if match.group("state") not in LIFECYCLE_STATES:
            sink.error(
                f"lifecycle state {match.group('state')!r}: a layer can require 'active' or "
                "'inactive'",
                line,
                col + offset + match.start("state"),
            )
            return []
        policy = _drift_policy(match.group("rest"), line, col + offset + match.start("rest"), sink)
        if policy is None:
            return []
        found.append(
            LifecycleBinding(
                layer,
                match.group("node"),
                match.group("state"),
                Position(line, col + offset + match.start("node")),
                sink.path,
                policy,
            )
        )
        offset += len(item) + 1
    return found
