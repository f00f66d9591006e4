"""Translation between the rosidl messages and the protocol's plain values."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from builtin_interfaces.msg import Time
from contextros_interfaces.msg import LayerInfo, ParticipantInfo, ParticipantStatus
from contextros_interfaces.msg import LayerState as LayerStateMsg
from contextros_interfaces.srv import Activate

from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerDeclaration,
    LayerState,
    ParticipantReport,
    RegistryView,
)
from contextros.protocol.relations import implied_by, merge_declarations


def stamp_to_seconds(stamp: Any) -> float:
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


def seconds_to_stamp(seconds: float) -> Any:
    sec = int(seconds)
    return Time(sec=sec, nanosec=int((seconds - sec) * 1e9))


def declaration_to_msg(declaration: LayerDeclaration) -> Any:
    return LayerInfo(
        name=declaration.name,
        excludes=sorted(declaration.excludes),
        required=sorted(declaration.requires),
        group=declaration.group,
        after=sorted(declaration.after),
        implies=sorted(declaration.implies),
    )


def declaration_from_msg(msg: Any) -> LayerDeclaration:
    return LayerDeclaration(
        name=msg.name,
        excludes=frozenset(msg.excludes),
        requires=frozenset(msg.required),
        group=msg.group,
        after=frozenset(msg.after),
        implies=frozenset(msg.implies),
    )


def state_to_msg(state: LayerState, wall_time: float) -> Any:
    return LayerStateMsg(
        epoch=state.epoch,
        active_layers=list(state.active),
        stamp=seconds_to_stamp(wall_time),
        requester=state.requester,
        reason=state.reason,
        manager_id=state.manager_id,
        status_period=state.status_period,
    )


def state_from_msg(msg: Any) -> LayerState:
    return LayerState(
        epoch=msg.epoch,
        active=tuple(msg.active_layers),
        requester=msg.requester,
        reason=msg.reason,
        stamp=stamp_to_seconds(msg.stamp),
        manager_id=msg.manager_id,
        status_period=msg.status_period,
    )


def report_to_msg(report: ParticipantReport, wall_time: float) -> Any:
    return ParticipantStatus(
        node=report.node,
        incarnation=report.incarnation,
        layers=[declaration_to_msg(d) for d in report.layers],
        applied_epoch=report.applied_epoch,
        applied_manager_id=report.applied_manager_id,
        active_layers=list(report.active),
        in_critical_section=report.in_critical_section,
        pending_epoch=report.pending_epoch,
        failed_epoch=report.failed_epoch,
        error=report.error,
        leaving=report.leaving,
        stamp=seconds_to_stamp(wall_time),
        hosted_nodes=list(report.hosted),
        manager_lost=report.manager_lost,
        vote_epoch=report.vote_epoch,
        vote_manager_id=report.vote_manager_id,
        vote_yes=report.vote_yes,
        vote_reason=report.vote_reason,
        language="Python",
    )


def report_from_msg(msg: Any) -> ParticipantReport:
    return ParticipantReport(
        node=msg.node,
        incarnation=msg.incarnation,
        layers=tuple(declaration_from_msg(d) for d in msg.layers),
        applied_epoch=msg.applied_epoch,
        applied_manager_id=msg.applied_manager_id,
        active=tuple(msg.active_layers),
        in_critical_section=msg.in_critical_section,
        pending_epoch=msg.pending_epoch,
        failed_epoch=msg.failed_epoch,
        error=msg.error,
        leaving=msg.leaving,
        hosted=tuple(msg.hosted_nodes),
        manager_lost=msg.manager_lost,
        vote_epoch=msg.vote_epoch,
        vote_manager_id=msg.vote_manager_id,
        vote_yes=msg.vote_yes,
        vote_reason=msg.vote_reason,
    )


def command_to_request(
    activate: Iterable[str],
    deactivate: Iterable[str],
    synchronous: bool,
    timeout: float,
    requester: str,
    reason: str,
    expect_nodes: Iterable[str] = (),
    expect_count: int = 0,
    atomic: bool = False,
) -> Any:
    return Activate.Request(
        activate=list(activate),
        deactivate=list(deactivate),
        synchronous=synchronous,
        timeout=float(timeout),
        requester=requester,
        reason=reason,
        expect_nodes=list(expect_nodes),
        expect_count=int(expect_count),
        atomic=atomic,
    )


def command_from_request(request_id: int, request: Any) -> ActivationCommand:
    return ActivationCommand(
        request_id=request_id,
        activate=tuple(request.activate),
        deactivate=tuple(request.deactivate),
        synchronous=request.synchronous,
        timeout=request.timeout,
        requester=request.requester,
        reason=request.reason,
        expect_nodes=tuple(request.expect_nodes),
        expect_count=request.expect_count,
        atomic=request.atomic,
    )


def fill_response(response: Any, result: ActivationResult) -> Any:
    response.success = result.success
    response.message = result.message
    response.epoch = result.epoch
    response.active_layers = list(result.active)
    response.acknowledged = list(result.acknowledged)
    response.not_acknowledged = list(result.not_acknowledged)
    response.elapsed = result.elapsed
    return response


def result_from_response(response: Any) -> ActivationResult:
    return ActivationResult(
        success=response.success,
        message=response.message,
        epoch=response.epoch,
        active=tuple(response.active_layers),
        acknowledged=tuple(response.acknowledged),
        not_acknowledged=tuple(response.not_acknowledged),
        elapsed=response.elapsed,
    )


def fill_query_response(response: Any, view: RegistryView, manager_id: str) -> Any:
    response.epoch = view.state.epoch
    response.active_layers = list(view.state.active)
    response.requester = view.state.requester
    response.reason = view.state.reason
    response.layers = [declaration_to_msg(d) for d in view.layers]
    response.implemented_by = [",".join(view.implemented_by.get(d.name, ())) for d in view.layers]
    response.participants = [
        ParticipantInfo(
            node=p.node,
            layers=list(p.layers),
            applied_epoch=p.applied_epoch,
            in_critical_section=p.in_critical_section,
            silent_for=p.silent_for,
            lagging=p.lagging,
            hosted_nodes=list(p.hosted),
            incarnation=p.incarnation,
            conflict=p.conflict,
            failed_epoch=p.failed_epoch,
            error=p.error,
        )
        for p in view.participants
    ]
    response.conflicts = list(view.conflicts)
    response.dropped = list(view.dropped)
    response.manager_id = manager_id
    response.recovering = view.recovering
    return response


def _implied_by(registry: Any) -> dict[str, list[str]]:
    declarations = merge_declarations(declaration_from_msg(layer) for layer in registry.layers)
    implied = implied_by(registry.active_layers, declarations)
    return {name: list(by) for name, by in implied.items()}


def registry_to_dict(registry: Any) -> dict[str, Any]:
    """A QueryRegistry answer as plain data (`contextros status --json`, the dashboard)."""
    from contextros.bindings.inference import layers_holding  # (only status needs it)

    return {
        "epoch": registry.epoch,
        "active": list(registry.active_layers),
        "requester": registry.requester,
        "reason": registry.reason,
        "manager_id": registry.manager_id,
        # Each active layer another active layer implies: {"Propulsion": ["Flight"]}.
        "implied_by": _implied_by(registry),
        "layers": [
            {
                "name": layer.name,
                "group": layer.group,
                "excludes": list(layer.excludes),
                "requires": list(layer.required),
                "after": list(layer.after),
                "implies": list(layer.implies),
                "implemented_by": [n for n in nodes.split(",") if n],
            }
            for layer, nodes in zip(registry.layers, registry.implemented_by, strict=False)
        ],
        "participants": [
            {
                "node": p.node,
                "layers": list(p.layers),
                "applied_epoch": p.applied_epoch,
                "in_critical_section": p.in_critical_section,
                "silent_for": round(p.silent_for, 3),
                "lagging": p.lagging,
                "hosted_nodes": list(p.hosted_nodes),
                "incarnation": p.incarnation,
                "conflict": p.conflict,
                # A manager older than these fields has none: nothing refused.
                "failed_epoch": getattr(p, "failed_epoch", 0),
                "error": getattr(p, "error", ""),
            }
            for p in registry.participants
        ],
        "conflicts": list(registry.conflicts),
        "dropped": list(registry.dropped),
        "recovering": registry.recovering,
        "declared_order": _declared_order(registry),
        "rules": [
            {
                "name": rule.name,
                "where": rule.where,
                "text": rule.text,
                "value": rule.value,
                "settled": rule.settled,
                "holding": rule.holding,
                "hold_left": round(rule.hold_left, 3),
                "hold": rule.hold,
                "hysteresis": rule.hysteresis,
                "relaxed": rule.relaxed,
                "readings": list(rule.readings),
                "error": rule.error,
                "last_firing": rule.last_firing,
                "last_outcome": rule.last_outcome,
            }
            for rule in registry.rules
        ],
        "bindings": [binding_to_dict(binding) for binding in registry.bindings],
        # The layers whose bindings all hold on the nodes (docs/ros-integration.md).
        "actual": layers_holding((b.layer, b.holds) for b in registry.bindings),
    }


def binding_to_dict(binding: Any) -> dict[str, Any]:
    """A BindingInfo as plain data: what it sets, its last result, what the manager read on
    its node, and its drift."""
    return {
        "layer": binding.layer,
        "kind": binding.kind,
        "node": binding.node,
        "parameter": binding.parameter,
        "value": binding.value,
        "where": binding.where,
        "ok": binding.ok,
        "last_result": binding.last_result,
        "last_time": stamp_to_seconds(binding.last_time) if binding.last_result else None,
        "policy": binding.policy or "report",
        "in_force": binding.in_force,
        "observed": binding.observed,
        "observed_time": stamp_to_seconds(binding.observed_time) if binding.observed else None,
        "holds": binding.holds,
        "drifted": binding.drifted,
        "drifted_since": stamp_to_seconds(binding.drifted_since) if binding.drifted else None,
        "drift_action": binding.drift_action,
    }


def _declared_order(registry: Any) -> list[str]:
    """The `after` declarations among the active layers: the manager composed them so."""
    active = list(registry.active_layers)
    return [
        f"{layer.name} after {earlier}"
        for layer in registry.layers
        if layer.name in active
        for earlier in layer.after
        if earlier in active
    ]
