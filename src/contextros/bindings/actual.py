"""The actual state of what layers set in ROS: the values and lifecycle states last read from
the nodes, against what the active layers set. Pure logic (no ROS): the manager feeds it
what it reads (`contextros.ros.binding_watch`) and the configuration ROS should reflect.

A binding is *in force* while its layer is active and it is the one its parameter (or
lifecycle node) follows (the outermost active layer binding it: `Bindings.desired`). It
*drifts* when it is in force and what was read differs from what it sets: someone else set
the parameter, or the node left the state. Each binding has a policy for that
(`on drift report|restore|infer`, docs/ros-integration.md): `restore_due` says which to set
back (bounded: a writer fighting back does not make the manager set it forever),
`contextros.bindings.inference` which layers to switch to.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

from contextros.bindings import Bindings, ResolveNode
from contextros.language.bindings import LifecycleBinding, ParameterBinding, ParameterValue

# (node, parameter): a parameter; (node, ""): a lifecycle node's state. Nodes resolved.
BindingKey = tuple[str, str]
Binding = ParameterBinding | LifecycleBinding
# Restores of one binding within this window (seconds) at most, then reported only.
RESTORE_LIMIT = 3
RESTORE_WINDOW = 30.0


@dataclass(frozen=True)
class Reading:
    """What a node had when the manager read it: a parameter value (None: not set, or of a
    type no binding sets) or a lifecycle state; `shown` as text; `noticed` (wall clock)
    when a change to it was first noticed (an event), `wall` when it was read."""

    value: ParameterValue | None
    shown: str
    wall: float
    noticed: float
    absent: bool = False  # the node is not in the ROS graph (nothing to set back)


@dataclass(frozen=True)
class Drift:
    """Binding `index` (of `ActualState.entries`) is in force and does not hold."""

    index: int
    binding: Binding
    key: BindingKey
    seen: str
    sets: str
    since: float  # wall clock
    policy: str

    @property
    def layer(self) -> str:
        return self.binding.layer.name

    def describe(self) -> str:
        """'/base max_speed = 1.5 (layer Slow sets 0.3)'."""
        node, name = self.key
        what = f"{node} {name} = {self.seen}" if name else f"lifecycle node {node} {self.seen}"
        return f"{what} (layer {self.layer} sets {self.sets})"


@dataclass(frozen=True)
class BindingState:
    """One binding's actual state, for status, watch and the dashboard."""

    in_force: bool
    reading: Reading | None
    holds: bool
    drifted_since: float | None
    action: str  # what the manager did about its drift ("" if nothing)


def key_of(binding: Binding, resolve: ResolveNode) -> BindingKey:
    if isinstance(binding, ParameterBinding):
        return (resolve(binding.node), binding.name)
    return (resolve(binding.node), "")


def shown_value(value: ParameterValue) -> str:
    """A binding's value as status shows it: `true`, `0.3`, `'eco'`."""
    return ("true" if value else "false") if isinstance(value, bool) else repr(value)


def sets(binding: Binding) -> ParameterValue:
    return binding.value if isinstance(binding, ParameterBinding) else binding.state


def holds(binding: Binding, value: ParameterValue | None) -> bool:
    """Whether `value` (read from the node) is what `binding` sets. A number is a number
    (the layer's `1` is a double parameter's 1.0), a boolean only a boolean."""
    wanted = sets(binding)
    if isinstance(wanted, bool) or isinstance(value, bool):
        return type(wanted) is type(value) and wanted == value
    if isinstance(wanted, (int, float)):
        return isinstance(value, (int, float)) and float(value) == float(wanted)
    return isinstance(value, str) and value == wanted


class ActualState:
    """Readings of every bound parameter and lifecycle node, and the drift of the bindings
    in force. Not thread-safe: the manager uses it from its executor only."""

    def __init__(
        self,
        bindings: Bindings,
        resolve: ResolveNode,
        *,
        restore_limit: int = RESTORE_LIMIT,
        restore_window: float = RESTORE_WINDOW,
    ) -> None:
        self.bindings = bindings
        self.resolve = resolve
        self.restore_limit = restore_limit
        self.restore_window = restore_window
        bound: list[Binding] = [*bindings.parameters, *bindings.lifecycles]
        self.entries: tuple[tuple[Binding, BindingKey], ...] = tuple(
            (binding, key_of(binding, resolve)) for binding in bound
        )
        self._keys = frozenset(key for _, key in self.entries)
        self.readings: dict[BindingKey, Reading] = {}
        self.applied: tuple[str, ...] = ()
        self._in_force: dict[BindingKey, int] = {}  # key -> index of the binding in force
        self._drifted_since: dict[int, float] = {}
        # Per key: when it was set back (monotonic), and why it no longer is.
        self._restores: dict[BindingKey, deque[float]] = {}
        self._given_up: dict[BindingKey, str] = {}
        self._actions: dict[int, str] = {}

    # -- what the manager watches -------------------------------------------------------

    def bound_keys(self) -> frozenset[BindingKey]:
        return self._keys

    def lifecycle_nodes(self) -> set[str]:
        return {key[0] for _, key in self.entries if not key[1]}

    def parameters_of(self) -> dict[str, set[str]]:
        """The bound parameters of each node."""
        found: dict[str, set[str]] = {}
        for _, (node, name) in self.entries:
            if name:
                found.setdefault(node, set()).add(name)
        return found

    # -- what it learns -----------------------------------------------------------------

    def read(self, key: BindingKey, reading: Reading) -> None:
        """What node and parameter `key` has (read from the node, or just set by the
        manager). A value that did not change keeps the time it was first noticed."""
        if key not in self.bound_keys():
            return
        previous = self.readings.get(key)
        if previous is not None and _same(previous.value, reading.value):
            reading = replace(reading, noticed=previous.noticed)
        self.readings[key] = reading
        self._update()

    def configuration(self, applied: Sequence[str], changed: Iterable[BindingKey] = ()) -> None:
        """ROS should now reflect `applied`; `changed` the keys its switch set: a binding
        the manager gave up setting back is tried again after a switch sets it."""
        for key in changed:
            self._given_up.pop(key, None)
            self._restores.pop(key, None)
        self.applied = tuple(applied)
        parameters, states = self.bindings.desired(self.applied, self.resolve)
        winners = {(key, layer) for key, (_, layer) in parameters.items()}
        winners |= {((node, ""), layer) for node, (_, layer) in states.items()}
        self._in_force = {
            key: index
            for index, (binding, key) in enumerate(self.entries)
            if (key, binding.layer.name) in winners
        }
        self._update()

    def _update(self) -> None:
        for index, (binding, key) in enumerate(self.entries):
            reading = self.readings.get(key)
            drifted = (
                self._in_force.get(key) == index
                and reading is not None
                and not holds(binding, reading.value)
            )
            if not drifted:
                self._drifted_since.pop(index, None)
                self._actions.pop(index, None)
            elif index not in self._drifted_since:
                assert reading is not None
                self._drifted_since[index] = reading.noticed

    # -- what it reports ----------------------------------------------------------------

    def drifts(self) -> list[Drift]:
        found = []
        for index, since in sorted(self._drifted_since.items()):
            binding, key = self.entries[index]
            reading = self.readings[key]
            seen = reading.shown
            found.append(Drift(index, binding, key, seen, _shown(binding), since, binding.policy))
        return found

    def state(self, index: int) -> BindingState:
        binding, key = self.entries[index]
        reading = self.readings.get(key)
        return BindingState(
            in_force=self._in_force.get(key) == index,
            reading=reading,
            holds=reading is not None and holds(binding, reading.value),
            drifted_since=self._drifted_since.get(index),
            action=self._actions.get(index, ""),
        )

    def acted(self, drift: Drift, action: str) -> None:
        """What the manager did about `drift` (shown until the binding holds again)."""
        if drift.index in self._drifted_since:
            self._actions[drift.index] = action

    # -- restore ------------------------------------------------------------------------

    def restore_due(self, now: float) -> list[Drift]:
        """The drifts to set back now (policy `restore`), each counted: a binding set back
        `restore_limit` times within `restore_window` s is not set back again (someone keeps
        changing it) until a switch sets it; `acted` then says so."""
        due = []
        for drift in self.drifts():
            if drift.policy != "restore" or self.readings[drift.key].absent:
                continue
            if drift.key in self._given_up:
                self._actions[drift.index] = self._given_up[drift.key]
                continue
            times = self._restores.setdefault(drift.key, deque())
            while times and now - times[0] > self.restore_window:
                times.popleft()
            if len(times) >= self.restore_limit:
                self._given_up[drift.key] = (
                    f"not set back: set back {len(times)} times within "
                    f"{self.restore_window:g} s and changed again each time (another writer "
                    "keeps setting it); reported only, until a switch sets it"
                )
                self._actions[drift.index] = self._given_up[drift.key]
                continue
            times.append(now)
            due.append(drift)
        return due

    def given_up(self, key: BindingKey) -> bool:
        return key in self._given_up


def _same(a: ParameterValue | None, b: ParameterValue | None) -> bool:
    return type(a) is type(b) and a == b


def _shown(binding: Binding) -> str:
    value = sets(binding)
    return shown_value(value) if isinstance(binding, ParameterBinding) else str(value)
