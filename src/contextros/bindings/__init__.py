"""Layers that drive ROS: what parameters and lifecycle states each configuration needs.

Pure logic (no ROS): the declarations of layer files (`parameter L: NODE NAME = VALUE`,
`lifecycle L: NODE active|inactive`, see `contextros.language.bindings`) and the plan of a
switch: which parameters to set or restore and which lifecycle nodes to move, from one
active set to the next. `contextros.ros.bindings` carries the plan out over the standard
parameter and lifecycle services, so it reaches any node, rclpy or rclcpp. docs/ros-integration.md.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from contextros.language.bindings import LifecycleBinding, ParameterBinding, ParameterValue
from contextros.language.diagnostics import LayerSyntaxError
from contextros.language.flavours import parse_files

ParameterKey = tuple[str, str]  # (node, parameter), the node name resolved
# From a declared node name to the fully qualified one (relative names: the manager's namespace).
ResolveNode = Callable[[str], str]


@dataclass(frozen=True)
class ParameterChange:
    """Set `key` to `value`, or back to what it was before any layer set it (`restore`)."""

    node: str
    name: str
    value: ParameterValue | None
    restore: bool
    layer: str  # the layer that wants it ("" for a restore)

    @property
    def key(self) -> ParameterKey:
        return (self.node, self.name)


@dataclass(frozen=True)
class LifecycleChange:
    """Bring lifecycle node `node` to `state` ("active"/"inactive"), or back (`restore`)."""

    node: str
    state: str | None
    restore: bool
    layer: str


@dataclass(frozen=True)
class Plan:
    parameters: tuple[ParameterChange, ...] = ()
    lifecycles: tuple[LifecycleChange, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.parameters or self.lifecycles)


class Bindings:
    """Every `parameter` and `lifecycle` declaration the manager applies, with node names
    resolved (`resolve` maps a declared node name to a fully qualified one)."""

    def __init__(
        self,
        parameters: Iterable[ParameterBinding],
        lifecycles: Iterable[LifecycleBinding],
    ) -> None:
        self.parameters = tuple(parameters)
        self.lifecycles = tuple(lifecycles)

    @classmethod
    def from_files(
        cls, paths: Iterable[str | os.PathLike[str]], language: str | None = None
    ) -> Bindings:
        parameters: list[ParameterBinding] = []
        lifecycles: list[LifecycleBinding] = []
        parsed, errors = parse_files(paths, language)
        for _, _, layer_file in parsed:
            parameters += layer_file.parameters
            lifecycles += layer_file.lifecycles
        if errors:
            raise LayerSyntaxError(errors)
        return cls(parameters, lifecycles)

    def __bool__(self) -> bool:
        return bool(self.parameters or self.lifecycles)

    def layers(self) -> frozenset[str]:
        names = {b.layer.name for b in self.parameters}
        return frozenset(names | {b.layer.name for b in self.lifecycles})

    def desired(
        self, active: Sequence[str], resolve: ResolveNode
    ) -> tuple[dict[ParameterKey, tuple[ParameterValue, str]], dict[str, tuple[str, str]]]:
        """What `active` asks of ROS: parameter values and lifecycle states, each with the
        layer asking. When several active layers ask for one thing, the outermost (the last
        in `active`) wins, as its partials do."""
        rank = {name: index for index, name in enumerate(active)}
        parameters: dict[ParameterKey, tuple[ParameterValue, str, int]] = {}
        for binding in self.parameters:
            layer = binding.layer.name
            if layer in rank:
                key = (resolve(binding.node), binding.name)
                if key not in parameters or rank[layer] >= parameters[key][2]:
                    parameters[key] = (binding.value, layer, rank[layer])
        states: dict[str, tuple[str, str, int]] = {}
        for lifecycle in self.lifecycles:
            layer = lifecycle.layer.name
            if layer in rank:
                node = resolve(lifecycle.node)
                if node not in states or rank[layer] >= states[node][2]:
                    states[node] = (lifecycle.state, layer, rank[layer])
        return (
            {k: (v[0], v[1]) for k, v in parameters.items()},
            {k: (v[0], v[1]) for k, v in states.items()},
        )

    def plan(self, old: Sequence[str], new: Sequence[str], resolve: ResolveNode) -> Plan:
        """The changes from configuration `old` to `new` (deterministic order: restores
        first, then sets, each sorted by node and name)."""
        old_parameters, old_states = self.desired(old, resolve)
        new_parameters, new_states = self.desired(new, resolve)
        parameter_changes = [
            ParameterChange(node, name, None, True, "")
            for (node, name) in sorted(old_parameters.keys() - new_parameters.keys())
        ]
        parameter_changes += [
            ParameterChange(node, name, value, False, layer)
            for (node, name), (value, layer) in sorted(new_parameters.items())
            if old_parameters.get((node, name), (None, ""))[0] != value
            or (node, name) not in old_parameters
        ]
        lifecycle_changes = [
            LifecycleChange(node, None, True, "")
            for node in sorted(old_states.keys() - new_states.keys())
        ]
        lifecycle_changes += [
            LifecycleChange(node, state, False, layer)
            for node, (state, layer) in sorted(new_states.items())
            if old_states.get(node, ("", ""))[0] != state
        ]
        return Plan(tuple(parameter_changes), tuple(lifecycle_changes))


# The lifecycle transitions (lifecycle_msgs/msg/Transition ids) that bring a node from a
# primary state to the wanted one, in order.
TRANSITIONS: dict[tuple[str, str], tuple[tuple[int, str], ...]] = {
    ("unconfigured", "inactive"): ((1, "configure"),),
    ("unconfigured", "active"): ((1, "configure"), (3, "activate")),
    ("inactive", "active"): ((3, "activate"),),
    ("active", "inactive"): ((4, "deactivate"),),
    ("inactive", "unconfigured"): ((2, "cleanup"),),
    ("active", "unconfigured"): ((4, "deactivate"), (2, "cleanup")),
}


def transitions(current: str, wanted: str) -> tuple[tuple[int, str], ...]:
    """The transitions from `current` to `wanted` (empty when already there); ValueError for
    a state that cannot get there (finalized, or a transition state)."""
    if current == wanted:
        return ()
    path = TRANSITIONS.get((current, wanted))
    if path is None:
        raise ValueError(f"it is {current!r}, from which ContextROS does not move it to {wanted!r}")
    return path
