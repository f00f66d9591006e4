"""What the binding driver must not forget across a restart, and its file
(`<state file>.bindings.json`, next to the manager's state file).

One record (`BindingMemory`), its invariants:

- `originals` hold, for every parameter and lifecycle node a layer changed, what it had
  before any layer changed it, until a switch that gives it back succeeds. They are on disk
  *before* the manager changes the node (write-ahead), so a manager killed at any point
  still gives the nodes back their own values.
- `applied` is the configuration ROS was last brought to completely.
- `unsettled` lists the configurations ROS may be partly at besides `applied`: a switch's
  target is added before its first change and removed when it succeeds or is rolled back
  completely. A switch killed halfway, or a rollback that failed, leaves it there: the next
  switch then sets or restores whatever any of them touched (`BindingDriver.plan`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import ParameterValue

from contextros.bindings import ParameterKey
from contextros.bindings.values import PRIMARY_STATES, from_json, to_json
from contextros.ros.durable_file import write_durably

Configuration = tuple[str, ...]


@dataclass
class BindingMemory:
    applied: Configuration = ()
    unsettled: tuple[Configuration, ...] = ()
    # (node, parameter) -> its ParameterValue before any layer set it.
    parameters: dict[ParameterKey, Any] = field(default_factory=dict)
    # lifecycle node -> its primary state before any layer moved it.
    states: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> str:
        parameters = [
            {"node": node, "name": name, **to_json(value)}
            for (node, name), value in sorted(self.parameters.items())
        ]
        return json.dumps(
            {
                "applied": list(self.applied),
                "unsettled": [list(configuration) for configuration in self.unsettled],
                "parameters": parameters,
                "lifecycles": dict(sorted(self.states.items())),
            },
            indent=2,
        )

    @classmethod
    def from_json(cls, text: str) -> BindingMemory:
        """ValueError, TypeError, KeyError or AttributeError for a damaged file. (A file
        written before `unsettled` existed has none.)"""
        data = json.loads(text)
        applied = _configuration(data["applied"])
        unsettled = tuple(_configuration(c) for c in data.get("unsettled", []))
        parameters = {
            (str(p["node"]), str(p["name"])): _parameter_value(p) for p in data["parameters"]
        }
        states = {str(node): str(state) for node, state in data["lifecycles"].items()}
        if not all(state in PRIMARY_STATES.values() for state in states.values()):
            raise ValueError("unexpected lifecycle states")
        return cls(applied, unsettled, parameters, states)


class BindingMemoryFile:
    """The record on disk: read once at start, written durably (write_durably) whenever
    it changed."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._written = ""

    def load(self) -> BindingMemory | None:
        """None without a file; the exceptions of `BindingMemory.from_json` and OSError."""
        if not self.path.exists():
            return None
        text = self.path.read_text(encoding="utf-8")
        memory = BindingMemory.from_json(text)
        self._written = memory.to_json()
        return memory

    def save(self, memory: BindingMemory) -> None:
        """Write `memory` unless the file has it already; OSError if it cannot be."""
        text = memory.to_json()
        if text == self._written:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        write_durably(self.path, text)
        self._written = text


def _configuration(names: Any) -> Configuration:
    if not isinstance(names, list) or not all(isinstance(name, str) for name in names):
        raise ValueError(f"not a list of layer names: {names!r}")
    return tuple(names)


def _parameter_value(data: Any) -> Any:
    """Kept across restarts: the types a layer can set (another is kept as not set: a
    restarted manager reads the value in place instead)."""
    kind, field_name, value = from_json(data)
    message = ParameterValue(type=kind)
    if field_name:
        setattr(message, field_name, value)
    return message
