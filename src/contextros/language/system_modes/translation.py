"""A system_modes model as a layer file (Python flavour) that behaves the same.

- Each mode of a system or node is a layer `<part>_<MODE>` (`/` in a part's name becomes
  `_`; `__DEFAULT__` is `<part>_DEFAULT`), with a docstring saying what it is.
- The modes of one part form a `group <part>`: one mode at a time. No layer of the group
  active is the part as nobody asked anything of it (system_modes' unconfigured system);
  activating `<part>_DEFAULT` is system_modes' "activate the part": active in `__DEFAULT__`.
- A node mode sets the node's parameters (`parameter`, those it inherits from `__DEFAULT__`
  included) and requires the node active (`lifecycle`): system_modes' modes specialise the
  active state.
- A system mode `implies` the layers of its parts' modes (`active` alone: the part's
  `__DEFAULT__`). A part it wants `inactive` (or `unconfigured`, which ContextROS's lifecycle
  bindings take as inactive, with a warning) is a `lifecycle` binding on that node, or on
  every node under that subsystem, and the system layer `excludes` that part's modes.
- `rules:` (if the system's target is X and a part is in state S, go to Y) become context
  rules on the part's lifecycle state and parameters (held 1 s: a part on its way does not
  count) when Y is inactive; the others are warnings naming the rule, and a comment in the
  output with the closest rule: nothing is dropped silently.
"""

from __future__ import annotations

import re

from contextros.language.diagnostics import DiagnosticSink
from contextros.language.system_modes.model import DEFAULT_MODE, Model, ModeRule, Part, PartState

DEFAULT_WORD = "DEFAULT"
# How long a part's state must hold before a converted rule acts. A node the manager itself
# activates passes through inactive (configure, then activate): system_modes' rules wait
# while a part is on its way, and so does this hold.
RULE_HOLD = "1 s"


def identifier(part: str) -> str:
    return part.replace("/", "_")


def layer_name(part: str, mode: str) -> str:
    return f"{identifier(part)}_{DEFAULT_WORD if mode == DEFAULT_MODE else mode}"


def _value(value: object) -> str:
    """A parameter value as `parameter` lines write it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return repr(str(value))  # a Python string literal, as the bindings read it


class _Translation:
    def __init__(self, model: Model, sink: DiagnosticSink, source_name: str) -> None:
        self.model = model
        self.sink = sink
        self.source_name = source_name
        self.lines: list[str] = []

    # -- checks across parts ---------------------------------------------------------------

    def check(self) -> None:
        """What only the whole model shows: unknown modes of parts, cycles, name clashes."""
        names: dict[str, str] = {}
        for part in self.model.parts.values():
            for mode in part.modes.values():
                name = layer_name(part.name, mode.name)
                if name in names:
                    self.sink.error(
                        f"mode {mode.name} of '{part.name}' and {names[name]} would both be "
                        f"layer '{name}'; rename one",
                        mode.at.line,
                        mode.at.col,
                    )
                names[name] = f"mode {mode.name} of '{part.name}'"
            for mode in part.modes.values():
                for child, state in mode.parts.items():
                    self.check_part_mode(part, child, state.mode, state.at.line, state.at.col)
            for rule in part.rules:
                for state in (rule.if_target, rule.new_target):
                    if state.mode and state.mode not in part.modes:
                        self.sink.error(
                            f"rule '{rule.name}' of '{part.name}': '{part.name}' has no mode "
                            f"{state.mode}",
                            state.at.line,
                            state.at.col,
                        )
        for part in self.model.parts.values():
            self.check_cycle(part, [])

    def check_part_mode(self, system: Part, child: str, mode: str, line: int, col: int) -> None:
        found = self.model.parts.get(child)
        if found is None:
            if mode and mode != DEFAULT_MODE:
                self.sink.error(
                    f"part '{child}' of '{system.name}' is not in the model, so it has no "
                    f"mode {mode}",
                    line,
                    col,
                )
        elif found.modes and mode and mode not in found.modes:
            self.sink.error(
                f"'{child}' has no mode {mode} (its modes: {', '.join(found.modes)})", line, col
            )
        elif not found.modes and found.kind == "system":
            self.sink.error(f"system '{child}' has no modes", line, col)

    def check_cycle(self, part: Part, path: list[str]) -> None:
        if part.name in path:
            cycle = " -> ".join([*path[path.index(part.name) :], part.name])
            self.sink.error(f"a system is its own part: {cycle}", part.at.line, part.at.col)
            return
        for child in self.children(part):
            found = self.model.parts.get(child)
            if found is not None and found.kind == "system":
                self.check_cycle(found, [*path, part.name])

    def children(self, part: Part) -> list[str]:
        named = [c for mode in part.modes.values() for c in mode.parts]
        return list(dict.fromkeys([*part.parts, *named]))

    # -- the layer file --------------------------------------------------------------------

    def nodes_under(self, name: str, seen: frozenset[str] = frozenset()) -> list[str]:
        """The nodes a part stands for: itself, or a subsystem's nodes, depth first."""
        part = self.model.parts.get(name)
        if part is None or part.kind == "node":
            return [name]
        if name in seen:
            return []
        found: list[str] = []
        for child in self.children(part):
            found += self.nodes_under(child, seen | {name})
        return list(dict.fromkeys(found))

    def layers_under(self, name: str, seen: frozenset[str] = frozenset()) -> list[str]:
        """The layers of a part's modes and of every part under it."""
        part = self.model.parts.get(name)
        if part is None or name in seen:
            return []
        found = [layer_name(name, mode) for mode in part.modes]
        for child in self.children(part):
            found += self.layers_under(child, seen | {name})
        return list(dict.fromkeys(found))

    def translate(self) -> str:
        out = self.lines
        out += [
            f"# Imported from {self.source_name} (a system_modes model) by `contextros "
            "import-modes`: a layer",
            "# per mode (<part>_<MODE>; __DEFAULT__ is <part>_DEFAULT), a group per system or "
            "node. Activate",
            "# <system>_DEFAULT where system_modes would activate the system.",
        ]
        for part in self.model.parts.values():
            if not part.modes:
                out += ["", f"# {part.kind} {part.name} ({self.where(part.at)}): no modes"]
                continue
            out += [
                "",
                f"# {part.kind} {part.name} ({self.where(part.at)})",
                f"group {identifier(part.name)}: "
                + ", ".join(layer_name(part.name, mode) for mode in part.modes),
            ]
            for mode in part.modes.values():
                out += [""] + (
                    self.node_layer(part, mode.name)
                    if part.kind == "node"
                    else self.system_layer(part, mode.name)
                )
            out += self.rules(part)
        return "\n".join(out) + "\n"

    def where(self, at: object) -> str:
        return f"{self.source_name}:{getattr(at, 'line', 0)}"

    def node_layer(self, part: Part, mode_name: str) -> list[str]:
        mode = part.modes[mode_name]
        name = layer_name(part.name, mode_name)
        lines = [
            f"layer {name}:",
            f'    """{part.name} in mode {mode_name} ({self.where(mode.at)})."""',
        ]
        for parameter, binding in mode.parameters.items():
            lines.append(f"parameter {name}: {part.name} {parameter} = {_value(binding.value)}")
        lines.append(f"lifecycle {name}: {part.name} active")
        return lines

    def system_layer(self, part: Part, mode_name: str) -> list[str]:
        mode = part.modes[mode_name]
        name = layer_name(part.name, mode_name)
        implies: list[str] = []
        excludes: list[str] = []
        lifecycle: list[str] = []
        for child, state in mode.parts.items():
            found = self.model.parts.get(child)
            if state.state == "active" and found is not None and found.modes:
                implies.append(layer_name(child, state.mode))
                continue
            if state.state == "unconfigured":
                self.sink.warning(
                    f"'{child}: unconfigured' in mode {mode_name} of '{part.name}' is taken as "
                    "inactive (a layer's lifecycle binding is active or inactive, and the "
                    "manager never cleans a node up)",
                    state.at.line,
                    state.at.col,
                )
            wanted = "active" if state.state == "active" else "inactive"
            lifecycle += [f"{node} {wanted}" for node in self.nodes_under(child)]
            if wanted == "inactive":
                excludes += self.layers_under(child)
        relations = f" implies {', '.join(implies)}" if implies else ""
        relations += f" excludes {', '.join(excludes)}" if excludes else ""
        told = ", ".join(f"{child} {state.text()}" for child, state in mode.parts.items())
        lines = [
            f"layer {name}{relations}:",
            f'    """{part.name} in mode {mode_name} ({self.where(mode.at)}): {told}."""',
        ]
        if lifecycle:
            lines.append(f"lifecycle {name}: {', '.join(lifecycle)}")
        return lines

    def rules(self, part: Part) -> list[str]:
        lines: list[str] = []
        for rule in part.rules:
            converted, why = self.rule(part, rule)
            if converted:
                lines += ["", f"# rule {rule.name} ({self.where(rule.at)})", converted]
                continue
            self.sink.warning(
                f"rule '{rule.name}' of '{part.name}' is not converted: {why}",
                rule.at.line,
                rule.at.col,
            )
            lines += [
                "",
                f"# NOT CONVERTED: rule {rule.name} ({self.where(rule.at)}): if {part.name}'s "
                f"target is {rule.if_target.text()} and {rule.part} is "
                f"{rule.part_state.text()}, go to {rule.new_target.text()}",
                f"#   ({why})",
            ]
        return lines

    def rule(self, part: Part, rule: ModeRule) -> tuple[str, str]:
        """The context rule for a system_modes rule, or '' and why there is none.

        system_modes applies a rule while the system's target is `if_target` and the part's
        actual state is `if_part`. A context rule cannot ask which layer is active, but
        deactivating a layer that is not active does nothing: a rule whose new target is
        inactive becomes `deactivate <system>_<if_target> when <part's state> for 1 s`.
        """
        name = re.sub(r"\W", "_", f"{identifier(part.name)}_{rule.name}")
        condition = self.part_condition(rule.part, rule.part_state)
        if not condition:
            return "", (
                f"'{rule.part}' is a system: its actual mode is inferred from its parts, "
                "which a rule's condition cannot read"
            )
        if rule.if_target.state != "active":
            return "", f"its target {rule.if_target.text()} has no layer (only modes do)"
        source = layer_name(part.name, rule.if_target.mode)
        if rule.new_target.state != "active":
            return f"rule {name}: deactivate {source} when {condition} for {RULE_HOLD}", ""
        target = layer_name(part.name, rule.new_target.mode)
        return "", (
            f"a context rule cannot ask whether {source} is the active mode; the closest is "
            f"'rule {name}: activate {target} when {condition} for {RULE_HOLD}', which also "
            f"fires when {part.name} is in another mode or none"
        )

    def part_condition(self, part_name: str, state: PartState) -> str:
        """A rule condition true when the part is in `state`, as system_modes infers it
        (a node's mode: the parameters its mode sets); '' for a system."""
        found = self.model.parts.get(part_name)
        if found is not None and found.kind == "system":
            return ""
        lifecycle = f"lifecycle {part_name} == {state.state}"
        if state.state != "active" or found is None or state.mode not in found.modes:
            return lifecycle
        parameters = found.modes[state.mode].parameters
        checks = [f"param {part_name}.{n} == {_value(p.value)}" for n, p in parameters.items()]
        return " and ".join([lifecycle, *checks])


def translate(model: Model, sink: DiagnosticSink, source_name: str) -> str:
    """The layer file for `model` ('' when `sink` has errors after the checks)."""
    translation = _Translation(model, sink, source_name)
    translation.check()
    if sink.has_errors:
        return ""
    return translation.translate()
