"""Which layers the robot is actually in, from what its nodes have (as system_modes' mode
inference does): the layers whose parameter and lifecycle bindings all hold. Pure logic on
`ActualState`'s readings.

With the `infer` policy, a drift that matches another layer becomes a switch: someone set
`max_speed` to the value layer Slow sets, and Slow's bindings all hold, so Slow is
activated (and the layers whose drifted bindings it explains deactivated), with the
observed values as the reason. docs/ros-integration.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from contextros.bindings.actual import ActualState, Drift, holds

MAX_REASON = 300


def layers_holding(bound: Iterable[tuple[str, bool]]) -> list[str]:
    """The layers whose bindings all hold, in first-seen order, from (layer, holds) pairs
    (one per binding; a binding not read yet does not hold)."""
    verdict: dict[str, bool] = {}
    for layer, holding in bound:
        verdict[layer] = verdict.get(layer, True) and holding
    return [layer for layer, holding in verdict.items() if holding]


def actual_layers(actual: ActualState) -> list[str]:
    """The layers with bindings that all hold now (layers without bindings cannot be seen
    on the nodes: they are in no actual set)."""
    return layers_holding(
        (binding.layer.name, actual.state(index).holds)
        for index, (binding, _) in enumerate(actual.entries)
    )


@dataclass(frozen=True)
class Inference:
    """Activate `activate`, deactivate `deactivate`, because of `reason`; or, when several
    layers match what is seen (`ambiguous`), nothing."""

    activate: tuple[str, ...]
    deactivate: tuple[str, ...]
    reason: str
    ambiguous: tuple[str, ...] = ()


def infer(actual: ActualState, active: Sequence[str]) -> Inference | None:
    """What the `infer` drifts (bindings of active layers that no longer hold) say: the one
    layer, not active, whose bindings all hold and that sets a drifted binding's parameter
    or node to what was seen. Several such layers: the ones explaining most drifts; still
    several: ambiguous. None without such drifts or layers."""
    drifts = [d for d in actual.drifts() if d.policy == "infer"]
    if not drifts:
        return None
    holding = set(actual_layers(actual)) - set(active)
    explained: dict[str, list[Drift]] = {}
    for binding, key in actual.entries:
        layer = binding.layer.name
        if layer not in holding:
            continue
        for drift in drifts:
            reading = actual.readings[drift.key]
            if key == drift.key and holds(binding, reading.value):
                explained.setdefault(layer, []).append(drift)
    if not explained:
        return None
    most = max(len(found) for found in explained.values())
    best = sorted(layer for layer, found in explained.items() if len(found) == most)
    if len(best) > 1:
        return Inference((), (), "", tuple(best))
    (layer,) = best
    matched = explained[layer]
    seen = "; ".join(drift.describe() for drift in matched)
    drifted_from = sorted({drift.layer for drift in matched})
    reason = f"inferred: {seen} is what layer {layer} sets (and its bindings all hold)"
    if len(reason) > MAX_REASON:
        reason = reason[: MAX_REASON - 3] + "..."
    return Inference((layer,), tuple(x for x in drifted_from if x != layer), reason)
