"""A system_modes model file (micro-ROS/system_modes' "SHM file"), read with positions.

The format, as system_modes documents it (its README, "Hierarchical System Modeling"):

    {system}:
      ros__parameters:
        type: system
        parts: {part} {part} ...          # a plain scalar, or a YAML list
        modes:
          __DEFAULT__:
            {part}: {state}[.{MODE}]
          {MODE}:
            {part}: {state}[.{MODE}]
        rules:                            # optional
          {name}: {if_target: ..., if_part: [{part}, {state}[.{MODE}]], new_target: ...}
    {node}:
      ros__parameters:
        type: node
        modes:
          __DEFAULT__:
            ros__parameters: {parameter: value, ...}
          {MODE}:
            ros__parameters: {parameter: value, ...}

As system_modes reads it: every mode starts from `__DEFAULT__` (its parameters, its parts'
states) and overrides some; a node mode may only set a parameter `__DEFAULT__` sets; `active`
without a mode means `active.__DEFAULT__`; part names are node names relative to the
manager's namespace. This reader is stricter where system_modes would silently go wrong: an
unknown key, a part a system does not list, an unknown mode or lifecycle state, a duplicate
key are errors at MODEL.yaml:line:col.

PyYAML (which rclpy brings) parses the text; it is imported when a model is read.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from contextros.language.bindings import ParameterValue
from contextros.language.diagnostics import DiagnosticSink
from contextros.language.positions import Position

DEFAULT_MODE = "__DEFAULT__"
PART_STATES = ("active", "inactive", "unconfigured")
RULE_KEYS = ("if_target", "if_part", "new_target")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")  # a mode's, or one part of a parameter's
_PART_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*")  # a node's


@dataclass(frozen=True)
class PartState:
    """`{state}[.{MODE}]`: what a system mode asks of one part (mode "" for none)."""

    state: str
    mode: str
    at: Position

    def text(self) -> str:
        return f"{self.state}.{self.mode}" if self.mode else self.state


@dataclass(frozen=True)
class Parameter:
    value: ParameterValue
    at: Position


@dataclass
class Mode:
    """One mode with what it inherits from `__DEFAULT__` already merged in."""

    name: str
    at: Position
    parameters: dict[str, Parameter] = field(default_factory=dict)  # a node's
    parts: dict[str, PartState] = field(default_factory=dict)  # a system's


@dataclass(frozen=True)
class ModeRule:
    """`if_target`, `if_part` and `new_target` of one entry of a system's `rules:`."""

    name: str
    at: Position
    if_target: PartState
    part: str
    part_state: PartState
    new_target: PartState


@dataclass
class Part:
    """A system or a node of the model, with its modes in the order the file gives them."""

    name: str
    kind: str  # "system" | "node"
    at: Position
    modes: dict[str, Mode] = field(default_factory=dict)
    parts: list[str] = field(default_factory=list)  # a system's
    rules: list[ModeRule] = field(default_factory=list)


@dataclass
class Model:
    parts: dict[str, Part] = field(default_factory=dict)


def _at(node: Any) -> Position:
    return Position(node.start_mark.line + 1, node.start_mark.column + 1)


class _Reader:
    """Walks the YAML node tree (which keeps positions), reporting into `sink`."""

    def __init__(self, sink: DiagnosticSink) -> None:
        import yaml  # type: ignore[import-untyped]  # rclpy brings it; only this reads YAML

        self.yaml = yaml
        self.sink = sink
        self.constructor = yaml.constructor.SafeConstructor()

    def error(self, message: str, node: Any) -> None:
        at = _at(node)
        self.sink.error(message, at.line, at.col)

    def mapping(self, node: Any, what: str) -> list[tuple[str, Any, Any]] | None:
        """(key, key node, value node) of a mapping, or None (reported) for anything else."""
        if not isinstance(node, self.yaml.MappingNode):
            self.error(f"{what} must be a mapping ('key: value' lines)", node)
            return None
        found: list[tuple[str, Any, Any]] = []
        seen: dict[str, Position] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, self.yaml.ScalarNode):
                self.error(f"a key in {what} must be a plain name", key_node)
                continue
            key = str(key_node.value)
            if key in seen:
                self.error(
                    f"duplicate key '{key}' in {what} (first at line {seen[key].line})", key_node
                )
                continue
            seen[key] = _at(key_node)
            found.append((key, key_node, value_node))
        return found

    def only_keys(
        self, items: list[tuple[str, Any, Any]], allowed: tuple[str, ...], what: str
    ) -> dict[str, tuple[Any, Any]]:
        known: dict[str, tuple[Any, Any]] = {}
        for key, key_node, value_node in items:
            if key in allowed:
                known[key] = (key_node, value_node)
            else:
                expected = ", ".join(f"'{a}'" for a in allowed)
                self.error(f"unknown key '{key}' in {what} (expected {expected})", key_node)
        return known

    def scalar(self, node: Any) -> Any:
        """The value rcl's YAML parser would give a scalar (YAML 1.1: `yes` is true)."""
        return self.constructor.construct_object(node)

    def string(self, node: Any, what: str) -> str | None:
        if not isinstance(node, self.yaml.ScalarNode) or not isinstance(self.scalar(node), str):
            self.error(f"{what} must be a string", node)
            return None
        return str(node.value)

    # -- the model ---------------------------------------------------------------------------

    def model(self, root: Any) -> Model:
        model = Model()
        items = self.mapping(root, "the model (one entry per system or node)")
        for name, key_node, value_node in items or ():
            part = self.part(name.lstrip("/"), key_node, value_node)
            if part is not None and part.name in model.parts:
                first = model.parts[part.name].at.line
                self.error(f"'{name}' is '{part.name}' again (first at line {first})", key_node)
            elif part is not None:
                model.parts[part.name] = part
        return model

    def part(self, name: str, key_node: Any, node: Any) -> Part | None:
        if not _PART_NAME.fullmatch(name):
            self.error(
                f"'{name}' is not a node name (names like 'drive_base', 'left/arm')", key_node
            )
            return None
        items = self.mapping(node, f"'{name}'")
        if items is None:
            return None
        top = self.only_keys(items, ("ros__parameters",), f"'{name}'")
        if "ros__parameters" not in top:
            self.error(f"'{name}' has no 'ros__parameters:'", key_node)
            return None
        what = f"'{name}' ros__parameters"
        body = self.mapping(top["ros__parameters"][1], what)
        if body is None:
            return None
        keys = {key: value for key, _, value in body}
        kind_node = keys.get("type")
        if kind_node is None:
            self.error(f"'{name}' has no 'type:' (system or node)", key_node)
            return None
        kind = self.string(kind_node, f"the type of '{name}'")
        if kind not in ("system", "node"):
            if kind is not None:
                self.error(f"type '{kind}' of '{name}': expected 'system' or 'node'", kind_node)
            return None
        allowed = ("type", "parts", "modes", "rules") if kind == "system" else ("type", "modes")
        fields = self.only_keys(body, allowed, f"{what} (a {kind})")
        part = Part(name, kind, _at(key_node))
        if "parts" in fields:
            part.parts = self.part_list(fields["parts"][1], name)
        if "modes" in fields:
            self.modes(part, fields["modes"][1])
        if "rules" in fields:
            self.rules(part, fields["rules"][1])
        return part

    def part_list(self, node: Any, system: str) -> list[str]:
        """`parts:` as the README writes it (names on lines of one plain scalar) or a list."""
        if isinstance(node, self.yaml.SequenceNode):
            names = [(self.string(item, f"a part of '{system}'"), item) for item in node.value]
        elif isinstance(node, self.yaml.ScalarNode):
            names = [(word, node) for word in str(node.value).split()]
        else:
            self.error(f"the parts of '{system}' must be names, one per line or a list", node)
            return []
        parts: list[str] = []
        for part, where in names:
            if part is None:
                continue
            if not _PART_NAME.fullmatch(part.lstrip("/")):
                self.error(f"part '{part}' of '{system}' is not a node name", where)
            elif part.lstrip("/") in parts:
                self.error(f"part '{part}' is listed twice in '{system}'", where)
            else:
                parts.append(part.lstrip("/"))
        return parts

    def modes(self, part: Part, node: Any) -> None:
        items = self.mapping(node, f"the modes of '{part.name}'")
        if not items:
            return
        default = next((item for item in items if item[0] == DEFAULT_MODE), None)
        if default is None:
            self.error(
                f"'{part.name}' has modes but no '{DEFAULT_MODE}' mode (every mode starts "
                "from it, as system_modes requires)",
                node,
            )
            return
        # __DEFAULT__ first: the other modes start from it wherever it stands in the file.
        for name, key_node, value_node in [default] + [i for i in items if i is not default]:
            if name != DEFAULT_MODE and not _NAME.fullmatch(name):
                self.error(
                    f"mode name '{name}' of '{part.name}': letters, digits and _ only", key_node
                )
                continue
            base = part.modes.get(DEFAULT_MODE)
            mode = Mode(
                name,
                _at(key_node),
                dict(base.parameters) if base else {},
                dict(base.parts) if base else {},
            )
            if part.kind == "node":
                self.node_mode(part, mode, value_node, base is None)
            else:
                self.system_mode(part, mode, value_node)
            part.modes[name] = mode
        part.modes = {name: part.modes[name] for name, _, _ in items if name in part.modes}

    def node_mode(self, part: Part, mode: Mode, node: Any, is_default: bool) -> None:
        what = f"mode {mode.name} of '{part.name}'"
        if isinstance(node, self.yaml.ScalarNode) and node.value in ("", "~", "null"):
            return  # a mode that changes nothing of __DEFAULT__
        items = self.mapping(node, what)
        if items is None:
            return
        fields = self.only_keys(items, ("ros__parameters",), what)
        if "ros__parameters" not in fields:
            return
        for name, value_node in self.parameters(fields["ros__parameters"][1], what, ""):
            if not is_default and name not in mode.parameters:
                self.error(
                    f"parameter '{name}' of {what} is not in its {DEFAULT_MODE} mode (a mode "
                    f"may only change the parameters {DEFAULT_MODE} sets)",
                    value_node,
                )
                continue
            value = self.parameter_value(value_node, name, what)
            if value is not None:
                mode.parameters[name] = Parameter(value, _at(value_node))

    def parameters(self, node: Any, what: str, prefix: str) -> list[tuple[str, Any]]:
        """Parameter names (nested mappings joined with dots, as ROS does) and value nodes."""
        if isinstance(node, self.yaml.ScalarNode) and node.value in ("", "~", "null"):
            return []
        found: list[tuple[str, Any]] = []
        for key, key_node, value_node in self.mapping(node, f"the parameters of {what}") or ():
            if not _NAME.fullmatch(key):
                self.error(
                    f"parameter name '{key}' of {what}: letters, digits and _ only", key_node
                )
            elif isinstance(value_node, self.yaml.MappingNode):
                found += self.parameters(value_node, what, f"{prefix}{key}.")
            else:
                found.append((f"{prefix}{key}", value_node))
        return found

    def parameter_value(self, node: Any, name: str, what: str) -> ParameterValue | None:
        value = self.scalar(node) if isinstance(node, self.yaml.ScalarNode) else None
        if isinstance(value, (bool, int, float, str)) and not (
            isinstance(value, float) and not math.isfinite(value)
        ):
            return value
        kind = "a list" if isinstance(node, self.yaml.SequenceNode) else repr(value)
        self.error(
            f"parameter '{name}' of {what} is {kind}: a layer's parameter binding takes a "
            "finite number, a string or a bool (not converted)",
            node,
        )
        return None

    def system_mode(self, part: Part, mode: Mode, node: Any) -> None:
        what = f"mode {mode.name} of '{part.name}'"
        if isinstance(node, self.yaml.ScalarNode) and node.value in ("", "~", "null"):
            return
        for name, key_node, value_node in self.mapping(node, what) or ():
            name = name.lstrip("/")
            if part.parts and name not in part.parts:
                self.error(
                    f"'{name}' in {what} is not a part of '{part.name}' (its parts: "
                    f"{', '.join(part.parts)})",
                    key_node,
                )
                continue
            state = self.part_state(value_node, f"part '{name}' in {what}")
            if state is not None:
                mode.parts[name] = state

    def part_state(self, node: Any, what: str) -> PartState | None:
        text = self.string(node, f"the state of {what}")
        if text is None:
            return None
        state, _, mode = text.partition(".")
        if state not in PART_STATES:
            self.error(
                f"'{text}' for {what}: expected active, inactive or unconfigured, optionally "
                "with a mode (active.MODE), in lower case",
                node,
            )
            return None
        if mode and state != "active":
            self.error(f"'{text}' for {what}: only an active part has a mode", node)
            return None
        if mode and mode != DEFAULT_MODE and not _NAME.fullmatch(mode):
            self.error(f"'{text}' for {what}: '{mode}' is not a mode name", node)
            return None
        return PartState(state, mode or (DEFAULT_MODE if state == "active" else ""), _at(node))

    def rules(self, part: Part, node: Any) -> None:
        for name, key_node, value_node in self.mapping(node, f"the rules of '{part.name}'") or ():
            what = f"rule '{name}' of '{part.name}'"
            fields = self.only_keys(self.mapping(value_node, what) or [], RULE_KEYS, what)
            missing = [key for key in RULE_KEYS if key not in fields]
            if missing:
                self.error(f"{what} has no {', '.join(missing)}", key_node)
                continue
            target = self.part_state(fields["if_target"][1], f"if_target of {what}")
            new = self.part_state(fields["new_target"][1], f"new_target of {what}")
            if_part = fields["if_part"][1]
            if not isinstance(if_part, self.yaml.SequenceNode) or len(if_part.value) != 2:
                self.error(f"if_part of {what} must be [PART, STATE]", if_part)
                continue
            part_name = self.string(if_part.value[0], f"the part in if_part of {what}")
            state = self.part_state(if_part.value[1], f"if_part of {what}")
            if part_name is not None and part.parts and part_name.lstrip("/") not in part.parts:
                self.error(
                    f"'{part_name}' in if_part of {what} is not a part of '{part.name}'",
                    if_part.value[0],
                )
                continue
            if None in (target, new, part_name, state):
                continue
            assert target and new and part_name and state
            part.rules.append(
                ModeRule(name, _at(key_node), target, part_name.lstrip("/"), state, new)
            )


def read_model(source: str, sink: DiagnosticSink) -> Model:
    """The model in `source`; problems go to `sink` (a YAML syntax error at its place)."""
    reader = _Reader(sink)
    yaml = reader.yaml
    try:
        documents = list(yaml.compose_all(source, Loader=yaml.SafeLoader))
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        problem = error.problem or error.context or "malformed YAML"
        sink.error(f"YAML: {problem}", line, col)
        return Model()
    documents = [document for document in documents if document is not None]
    if not documents:
        sink.error("the model is empty (no system and no node)", 1, 1)
        return Model()
    if len(documents) > 1:
        at = _at(documents[1])
        sink.error("a model is one YAML document; this is a second one", at.line, at.col)
        return Model()
    return reader.model(documents[0])
