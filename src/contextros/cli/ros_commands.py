"""`contextros` subcommands for the distributed part: the manager and its clients.

rclpy is imported inside the commands only, so `contextros --help` and the language
commands work on machines without ROS 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from contextros.errors import LayerError

if TYPE_CHECKING:
    from contextros.ros import LayerClient

# Exit statuses: 0 success, 1 the manager refused or nodes did not acknowledge,
# 3 no manager reachable (argparse itself uses 2 for usage errors).
FAILED = 1
NO_MANAGER = 3


def register(commands: Any) -> None:
    """Add this part's subcommands to the `contextros` parser."""
    manager = commands.add_parser(
        "manager", help="run the Layer manager (registry, activation service, state broadcast)"
    )
    manager.add_argument(
        "--state-file",
        type=Path,
        help="remember the state here, so a restarted manager never reuses an epoch",
    )
    manager.add_argument(
        "--liveness-timeout",
        type=float,
        default=2.0,
        metavar="S",
        help="drop a participant silent for this long (default 2 s)",
    )
    manager.add_argument(
        "--default-timeout",
        type=float,
        default=5.0,
        metavar="S",
        help="timeout of synchronous activations that give none (default 5 s)",
    )
    manager.add_argument(
        "--recovery-window",
        type=float,
        default=1.0,
        metavar="S",
        help="listen to participants this long before the first state (default 1 s)",
    )
    manager.set_defaults(run=run_manager)

    activate = commands.add_parser("activate", help="activate layers on every context node")
    activate.add_argument("layers", nargs="+", metavar="LAYER")
    _add_command_options(activate)
    activate.set_defaults(run=lambda args: _send(args, on=args.layers, off=[]))

    deactivate = commands.add_parser("deactivate", help="deactivate layers on every context node")
    deactivate.add_argument("layers", nargs="+", metavar="LAYER")
    _add_command_options(deactivate)
    deactivate.set_defaults(run=lambda args: _send(args, on=[], off=args.layers))

    switch = commands.add_parser(
        "switch", help="deactivate some layers and activate others in one atomic step"
    )
    switch.add_argument("--on", nargs="+", default=[], metavar="LAYER", help="layers to activate")
    switch.add_argument(
        "--off", nargs="+", default=[], metavar="LAYER", help="layers to deactivate"
    )
    _add_command_options(switch)
    switch.set_defaults(run=lambda args: _send(args, on=args.on, off=args.off))

    status = commands.add_parser(
        "status", help="show the active layers, the layers, the nodes and who lags"
    )
    _add_connection_options(status)
    status.add_argument("--json", action="store_true", help="print JSON instead of tables")
    status.set_defaults(run=run_status)

    watch = commands.add_parser("watch", help="stream layer switches and their latency")
    watch.add_argument(
        "--count", type=int, metavar="N", help="stop after N switches (and their acknowledgements)"
    )
    watch.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    watch.add_argument("--json", action="store_true", help="one JSON object per line")
    watch.set_defaults(run=run_watch)


def _add_connection_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--wait-manager",
        type=float,
        default=5.0,
        metavar="S",
        help="how long to look for the manager (default 5 s)",
    )


def _add_command_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sync",
        action="store_true",
        help="return only once every live node applied the new state (else: once published)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=0.0,
        metavar="S",
        help="synchronous timeout (default: the manager's)",
    )
    parser.add_argument("--reason", default="", help="recorded with the new state")
    parser.add_argument("--json", action="store_true", help="print the answer as JSON")
    _add_connection_options(parser)


# -- the manager ----------------------------------------------------------------------------


def run_manager(args: argparse.Namespace) -> int:
    import rclpy

    from contextros.protocol import ManagerSettings
    from contextros.ros import LayerManagerNode, spin_nodes

    settings = ManagerSettings(
        liveness_timeout=args.liveness_timeout,
        default_timeout=args.default_timeout,
        recovery_window=args.recovery_window,
    )
    rclpy.init()
    try:
        node = LayerManagerNode(settings=settings, state_file=args.state_file)
    except LayerError as error:
        print(f"contextros manager: {error}", file=sys.stderr)
        rclpy.try_shutdown()
        return FAILED
    spin_nodes([node])
    rclpy.try_shutdown()
    return 0


# -- clients --------------------------------------------------------------------------------


@contextmanager
def _client(purpose: str) -> Iterator[LayerClient]:
    """A LayerClient on a short-lived node of this command's own, torn down on the way out."""
    import rclpy
    from rclpy.node import Node

    from contextros.ros import LayerClient

    rclpy.init()
    node = Node(f"contextros_{purpose}_{os.getpid()}")
    try:
        yield LayerClient(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _send(args: argparse.Namespace, on: list[str], off: list[str]) -> int:
    if not on and not off:
        print("contextros: name layers to activate (--on) or deactivate (--off)", file=sys.stderr)
        return 2
    with _client("cli") as client:
        try:
            client.wait_for_manager(args.wait_manager)
        except LayerError as error:
            print(f"contextros: {error}", file=sys.stderr)
            return NO_MANAGER
        try:
            result = client.request(
                on, off, synchronous=args.sync, timeout=args.timeout, reason=args.reason
            )
        except LayerError as error:
            print(f"contextros: {error}", file=sys.stderr)
            return FAILED
    if args.json:
        print(json.dumps(result.__dict__ | {"active": list(result.active)}, default=list))
    else:
        layers = ", ".join(result.active) or "none"
        print(f"epoch {result.epoch}: active [{layers}]")
        if result.acknowledged or result.not_acknowledged:
            print(
                f"acknowledged by {len(result.acknowledged)} node(s) "
                f"in {result.elapsed * 1000:.1f} ms"
            )
    if not result.success:
        print(f"contextros: {result.message}", file=sys.stderr)
        return FAILED
    return 0


def run_status(args: argparse.Namespace) -> int:
    with _client("status") as client:
        try:
            client.wait_for_manager(args.wait_manager)
            registry = client.query()
        except LayerError as error:
            print(f"contextros: {error}", file=sys.stderr)
            return NO_MANAGER
    if args.json:
        print(json.dumps(_registry_as_dict(registry), indent=2))
    else:
        print(_registry_as_text(registry))
    return 0


def _registry_as_dict(registry: Any) -> dict[str, Any]:
    return {
        "epoch": registry.epoch,
        "active": list(registry.active_layers),
        "requester": registry.requester,
        "reason": registry.reason,
        "manager_id": registry.manager_id,
        "layers": [
            {
                "name": layer.name,
                "group": layer.group,
                "excludes": list(layer.excludes),
                "requires": list(layer.requires),
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
            }
            for p in registry.participants
        ],
        "dropped": list(registry.dropped),
        "recovering": registry.recovering,
    }


def _table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(cell)) for cell in column) for column in zip(header, *rows, strict=False)]
    lines = [header, ["-" * w for w in widths], *rows]
    return "\n".join(
        "  ".join(str(cell).ljust(w) for cell, w in zip(line, widths, strict=False)).rstrip()
        for line in lines
    )


def _registry_as_text(registry: Any) -> str:
    data = _registry_as_dict(registry)
    active = ", ".join(data["active"]) or "none"
    by = f"{data['requester'] or '?'}: {data['reason'] or '-'}"
    parts = [f"epoch {data['epoch']}  active [{active}]  ({by})", ""]
    if data["recovering"]:
        parts[0] += "  - the manager is still recovering (listening to participants)"
    layer_rows = [
        [
            layer["name"],
            "yes" if layer["name"] in data["active"] else "",
            layer["group"],
            ", ".join(layer["excludes"]),
            ", ".join(layer["requires"]),
            ", ".join(layer["implemented_by"]),
        ]
        for layer in data["layers"]
    ]
    parts.append(_table(["LAYER", "ACTIVE", "GROUP", "EXCLUDES", "REQUIRES", "NODES"], layer_rows))
    parts.append("")
    node_rows = [
        [
            p["node"],
            str(p["applied_epoch"]),
            "LAGS" if p["lagging"] else "ok",
            "yes" if p["in_critical_section"] else "",
            f"{p['silent_for']:.1f} s",
            ", ".join(p["layers"]),
            ", ".join(p["hosted_nodes"]),
        ]
        for p in data["participants"]
    ]
    header = ["NODE", "EPOCH", "STATE", "CRITICAL", "LAST HEARD", "LAYERS", "ALSO FOR"]
    parts.append(_table(header, node_rows))
    if data["dropped"]:
        parts += ["", f"dropped: {', '.join(data['dropped'])}"]
    return "\n".join(parts)


def run_watch(args: argparse.Namespace) -> int:
    import rclpy
    from contextros_interfaces.msg import LayerState, ParticipantStatus
    from rclpy.node import Node

    from contextros.ros import STATE_QOS, STATE_TOPIC, STATUS_QOS, STATUS_TOPIC, spin_nodes
    from contextros.ros.messages import stamp_to_seconds

    rclpy.init()
    node = Node(f"contextros_watch_{os.getpid()}")
    switches = 0
    last_switch = 0.0
    # Per epoch: when it was published, the live nodes that must apply it, and who has not.
    waiting: dict[int, tuple[float, int, set[str]]] = {}
    last_heard: dict[str, float] = {}
    applied: dict[str, int] = {}

    def live_nodes() -> set[str]:
        now = time.monotonic()
        return {n for n, t in last_heard.items() if now - t < 2.0}

    def on_state(msg: Any) -> None:
        nonlocal switches, last_switch
        published = stamp_to_seconds(msg.stamp)
        # The first message is the state as it stood when we connected (transient local).
        first = switches == 0 and last_switch == 0.0
        record = {
            "event": "current" if first else "state",
            "epoch": msg.epoch,
            "active": list(msg.active_layers),
            "requester": msg.requester,
            "reason": msg.reason,
            "delivery_ms": round((time.time() - published) * 1000, 3),
        }
        last_switch = time.monotonic()
        _print_watch(args.json, record)
        if first:
            return
        switches += 1
        pending = {n for n in live_nodes() if applied.get(n, 0) < msg.epoch}
        waiting[msg.epoch] = (published, len(pending), pending)
        if not pending:
            _report_applied(args.json, published, msg.epoch, 0)
            del waiting[msg.epoch]

    def on_status(msg: Any) -> None:
        if msg.leaving:
            if last_heard.pop(msg.node, None) is not None:
                _print_watch(args.json, {"event": "node-left", "node": msg.node})
        else:
            if msg.node not in live_nodes():
                _print_watch(args.json, {"event": "node", "node": msg.node})
            last_heard[msg.node] = time.monotonic()
        applied[msg.node] = msg.applied_epoch
        for epoch, (published, count, pending) in sorted(waiting.items()):
            if msg.applied_epoch >= epoch or msg.leaving:
                pending.discard(msg.node)
            if not pending:
                del waiting[epoch]
                _report_applied(args.json, published, epoch, count)

    def finished() -> bool:
        # After the last counted switch, wait (a little) for its acknowledgements too.
        if args.count is None or switches < args.count:
            return False
        return not waiting or time.monotonic() - last_switch > 2.0

    node.create_subscription(LayerState, STATE_TOPIC, on_state, STATE_QOS)
    node.create_subscription(ParticipantStatus, STATUS_TOPIC, on_status, STATUS_QOS)
    spin_nodes([node], until=finished, timeout=args.duration)
    rclpy.try_shutdown()
    return 0


def _report_applied(as_json: bool, published: float, epoch: int, nodes: int) -> None:
    latency = (time.time() - published) * 1000
    _print_watch(
        as_json,
        {"event": "applied", "epoch": epoch, "nodes": nodes, "latency_ms": round(latency, 3)},
    )


def _print_watch(as_json: bool, record: dict[str, Any]) -> None:
    if as_json:
        print(json.dumps(record), flush=True)
    elif record["event"] in ("node", "node-left"):
        verb = "is here" if record["event"] == "node" else "left"
        print(f"node {record['node']} {verb}", flush=True)
    elif record["event"] in ("current", "state"):
        active = ", ".join(record["active"]) or "none"
        who = f"{record['requester'] or '?'}: {record['reason'] or '-'}"
        timing = (
            "current state"
            if record["event"] == "current"
            else f"delivered in {record['delivery_ms']:.2f} ms"
        )
        print(f"epoch {record['epoch']:>6}  [{active}]  ({who})  {timing}", flush=True)
    else:
        print(
            f"epoch {record['epoch']:>6}  applied by all {record['nodes']} live node(s) "
            f"{record['latency_ms']:.2f} ms after publication",
            flush=True,
        )
