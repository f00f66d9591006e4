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
from contextlib import ExitStack, contextmanager
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from contextros.cli import exits
from contextros.cli.answered_in_child import INTERRUPTED, answered_in_child
from contextros.cli.binding_status import (
    actual_line,
    binding_rows,
    drift_lines,
    drift_record_line,
)
from contextros.cli.option_types import ACTIVATION_TIMEOUT, MAX_TIMEOUT, Count, Seconds
from contextros.cli.ros_arguments import namespace_problem, rclpy_arguments
from contextros.errors import LayerError
from contextros.protocol.relations import listed_with_implied

if TYPE_CHECKING:
    from contextros.ros import LayerClient

# Exit statuses: 0 success, 1 the manager refused, nodes did not acknowledge or the outcome
# is unknown, 3 no manager reachable, 130 interrupted (argparse itself uses 2 for usage).
FAILED = 1
USAGE = 2
NO_MANAGER = 3
# The exit status of an answer that is not a result, by its outcome.
_OUTCOME_STATUS = {"usage": USAGE, "no_manager": NO_MANAGER, "interrupted": INTERRUPTED}
# Seconds a long-running command (manager, watch, record, dashboard) may take to tear its
# node down once stopped: see contextros.ros.spinning.bounded_teardown.
TEARDOWN_LIMIT = 10.0
# The commands the daemon answers (contextros.cli.daemon) when it runs.
DAEMON_SERVED = ("activate", "deactivate", "switch", "status")


class RosArgumentsError(Exception):
    """The ROS arguments or the namespace given on the command line are not usable."""


def add_namespace_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--namespace",
        metavar="NS",
        help="the robot's namespace (e.g. /robot1): the manager's topics and services are "
        "resolved in it; same as --ros-args -r __ns:=NS",
    )


@contextmanager
def ros_session(args: argparse.Namespace) -> Iterator[None]:
    """rclpy initialised with the command line's ROS arguments and --namespace."""
    import rclpy

    namespace = getattr(args, "namespace", None)
    if namespace is not None and (problem := namespace_problem(namespace)):
        raise RosArgumentsError(problem)
    arguments = rclpy_arguments("contextros", getattr(args, "ros_arguments", []), namespace)
    try:
        rclpy.init(args=arguments)
    except Exception as error:  # rclpy raises its RCLError, not exported as a type
        raise RosArgumentsError(
            f"invalid ROS arguments {' '.join(arguments[1:])!r}: {error}"
        ) from error
    try:
        yield
    finally:
        if not rclpy.ok():  # not shut down by us yet: by rclpy's signal handler
            exits.ros_context_shut_by_signal = True
        rclpy.try_shutdown()


def usage_error(error: RosArgumentsError) -> int:
    print(f"contextros: {error}", file=sys.stderr)
    return USAGE


def register(commands: Any) -> None:
    """Add this part's subcommands to the `contextros` parser."""
    manager = commands.add_parser(
        "manager", help="run the Layer manager (registry, activation service, state broadcast)"
    )
    manager.add_argument(
        "--state-file",
        type=Path,
        help="remember the state here, so a restarted manager never reuses an epoch (and, "
        "with --layers, the parameter values to restore in FILE.bindings.json)",
    )
    manager.add_argument(
        "--liveness-timeout",
        type=Seconds(positive=True),
        default=3.0,
        metavar="S",
        help="drop a participant silent for this long (default 3 s: 12 heartbeats)",
    )
    manager.add_argument(
        "--status-rate",
        type=Count(least=1),
        default=1000,
        metavar="N",
        help="statuses per second asked of the participants at most: beyond N/4 of them their "
        "heartbeat slows down and the liveness timeout grows with it (default 1000)",
    )
    manager.add_argument(
        "--default-timeout",
        type=Seconds(positive=True, most=MAX_TIMEOUT),
        default=5.0,
        metavar="S",
        help="timeout of synchronous activations that give none (default 5 s)",
    )
    manager.add_argument(
        "--recovery-window",
        type=Seconds(),
        default=1.0,
        metavar="S",
        help="listen to participants this long before the first state (default 1 s)",
    )
    manager.add_argument(
        "--unknown-layer-grace",
        type=Seconds(),
        default=2.0,
        metavar="S",
        help="after recovery, a command naming a layer nobody implements yet waits this long "
        "for its participant before it is refused (default 2 s)",
    )
    manager.add_argument(
        "--binding-timeout",
        type=Seconds(positive=True, most=MAX_TIMEOUT),
        default=10.0,
        metavar="S",
        help="how long each parameter or lifecycle call of the layers' bindings waits for the "
        "node's answer (default 10 s; within a command, no longer than its caller waits)",
    )
    manager.add_argument(
        "--layers",
        "--rules",
        dest="layer_files",
        nargs="+",
        default=[],
        metavar="FILE.layers",
        help="run the context rules (docs/rules.md) and apply the parameter and lifecycle "
        "declarations (docs/ros-integration.md) of these layer files",
    )
    add_namespace_option(manager)
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
        "--count",
        type=Count(least=1),
        metavar="N",
        help="stop after N switches (and their acknowledgements)",
    )
    watch.add_argument(
        "--duration", type=Seconds(positive=True), metavar="S", help="stop after S seconds"
    )
    watch.add_argument("--json", action="store_true", help="one JSON object per line")
    add_namespace_option(watch)
    watch.set_defaults(run=run_watch)


def _add_connection_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--wait-manager",
        type=Seconds(),
        default=5.0,
        metavar="S",
        help="how long to look for the manager (default 5 s)",
    )
    parser.add_argument(
        "--no-daemon",
        action="store_true",
        help="ask the manager from this process, not through the daemon (`contextros daemon`)",
    )
    add_namespace_option(parser)


def _add_command_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sync",
        action="store_true",
        help="return only once every live node applied the new state (else: once published)",
    )
    parser.add_argument(
        "--timeout",
        type=ACTIVATION_TIMEOUT,
        default=0.0,
        metavar="S",
        help=(
            "the command's deadline, counted from its arrival at the manager: refused, never "
            "carried out, if it has not started by then (default: the manager's)"
        ),
    )
    parser.add_argument(
        "--atomic",
        action="store_true",
        help="every node votes first: all switch or none does (the answer names who vetoed)",
    )
    parser.add_argument(
        "--expect",
        nargs="+",
        default=[],
        metavar="NODE",
        help="with --sync: fail unless these nodes applied it (even if the manager dropped them)",
    )
    parser.add_argument(
        "--expect-count",
        type=Count(),
        default=0,
        metavar="N",
        help="with --sync: fail unless at least N nodes applied it",
    )
    parser.add_argument("--reason", default="", help="recorded with the new state")
    parser.add_argument("--json", action="store_true", help="print the answer as JSON")
    _add_connection_options(parser)


# -- the manager ----------------------------------------------------------------------------


# Fast DDS reads its default profile file from these variables (the second: Fast DDS 2).
_FASTDDS_PROFILE_VARIABLES = ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE")


def use_packaged_profile(name: str) -> None:
    """Use the Fast DDS profile `name` shipped in `contextros/ros/` (the manager's: it
    announces itself often; both: a reader repairs a missed first message fast); only with
    Fast DDS, and never over a profile file the user chose. Call before rclpy starts."""
    rmw = os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    if not rmw.startswith("rmw_fastrtps") or any(
        os.environ.get(variable) for variable in _FASTDDS_PROFILE_VARIABLES
    ):
        return
    profile = Path(__file__).resolve().parent.parent / "ros" / name
    if profile.is_file():
        os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] = str(profile)


def run_manager(args: argparse.Namespace) -> int:
    use_packaged_profile("manager_discovery.xml")  # before rclpy creates the participant
    from contextros.protocol import ManagerSettings
    from contextros.ros import LayerManagerNode, spin_nodes

    settings = ManagerSettings(
        liveness_timeout=args.liveness_timeout,
        status_rate=args.status_rate,
        default_timeout=args.default_timeout,
        recovery_window=args.recovery_window,
        unknown_layer_grace=args.unknown_layer_grace,
    )
    rules = bindings = None
    if args.layer_files:
        import dataclasses

        from contextros.bindings import Bindings
        from contextros.cli.language_commands import not_layers
        from contextros.language.checker import check_files
        from contextros.language.declarations import declarations_from_files
        from contextros.language.diagnostics import LayerLanguageError
        from contextros.ros.message_types import installed_message_type
        from contextros.rules import RuleSet

        # Refused: what `contextros check` refuses in each file, and what the files together
        # have (docs/rules.md), every error listed.
        not_files = [(name, not_layers(Path(name), directories=False)) for name in args.layer_files]
        found = check_files(
            [name for name, why in not_files if not why], message_types=installed_message_type
        )
        errors = "\n".join(
            [f"{name}: error: {why}" for name, why in not_files if why]
            + [d.render() for d in found if d.is_error]
        )
        if errors:
            print(f"contextros manager: the layer files have errors:\n{errors}", file=sys.stderr)
            return USAGE
        try:
            rules = RuleSet.from_files(args.layer_files)
            bindings = Bindings.from_files(args.layer_files)
            # Their layers' relations (`after` too) join the participants' declarations,
            # as in `rules replay`.
            settings = dataclasses.replace(
                settings, layer_files=tuple(declarations_from_files(args.layer_files))
            )
        except LayerError as error:
            listed = error.render() if isinstance(error, LayerLanguageError) else str(error)
            print(f"contextros manager: the layer files have errors:\n{listed}", file=sys.stderr)
            return USAGE
    if args.state_file is not None:
        from contextros.ros.manager_node import StateFile

        try:  # refused now rather than found out at the first state, silently
            StateFile(args.state_file).check_writable()
        except OSError as error:
            print(
                f"contextros manager: cannot write the state file {args.state_file}: "
                f"{error.strerror or error}",
                file=sys.stderr,
            )
            return USAGE
    try:
        with ros_session(args):
            try:
                node = LayerManagerNode(
                    settings=settings,
                    state_file=args.state_file,
                    rules=rules,
                    bindings=bindings,
                    binding_timeout=args.binding_timeout,
                )
            except LayerError as error:
                print(f"contextros manager: {error}", file=sys.stderr)
                return FAILED
            spin_nodes(
                [node],
                until=lambda: bool(node.stepped_down),
                lean=True,
                teardown_limit=TEARDOWN_LIMIT,
            )
    except RosArgumentsError as error:
        return usage_error(error)
    if node.stepped_down:  # another manager runs this namespace (the log said which)
        return USAGE
    return 0


# -- clients --------------------------------------------------------------------------------


def _open_client(args: argparse.Namespace, purpose: str, teardown: ExitStack) -> LayerClient:
    """A LayerClient on a short-lived node of this command's own (in the namespace the
    command line gives); the node and rclpy are torn down when `teardown` closes."""
    from contextros.ros import LayerClient
    from contextros.ros.client import quiet_node

    use_packaged_profile("client_discovery.xml")
    teardown.enter_context(ros_session(args))
    node = quiet_node(f"contextros_{purpose}_{os.getpid()}")
    teardown.callback(node.destroy_node)
    return LayerClient(node)


def _send(args: argparse.Namespace, on: list[str], off: list[str]) -> int:
    if not on and not off:
        print("contextros: name layers to activate (--on) or deactivate (--off)", file=sys.stderr)
        return 2
    if (args.expect or args.expect_count) and not (args.sync or args.atomic):
        print("contextros: --expect and --expect-count need --sync or --atomic", file=sys.stderr)
        return 2
    request = {
        "command": "activate",
        "on": on,
        "off": off,
        "sync": args.sync,
        "timeout": args.timeout,
        "atomic": args.atomic,
        "expect": args.expect,
        "expect_count": args.expect_count,
        "reason": args.reason,
        "requester": _requester(),  # this command's process, whoever sends the command
    }
    answer = _through_daemon(args, request)
    if answer is not None:
        return _report(args, on, answer)
    with answered_in_child(
        partial(_asked_directly, args, request),
        "whether it was carried out is unknown; see `contextros status`",
    ) as answer:
        return _report(args, on, answer)


def _report(args: argparse.Namespace, on: list[str], answer: dict[str, Any]) -> int:
    """Print an activation's answer (the daemon's or this command's own); its exit status."""
    if answer["outcome"] != "result":
        print(f"contextros: {answer['message']}", file=sys.stderr)
        return _OUTCOME_STATUS.get(answer["outcome"], FAILED)
    return _print_result(args, on, answer["result"])


def _requester() -> str:
    from contextros.identity import default_requester

    return default_requester()


def _through_daemon(args: argparse.Namespace, request: dict[str, Any]) -> dict[str, Any] | None:
    """The daemon's answer (see contextros.cli.daemon), or None: ask the manager directly.
    Not with --no-daemon, nor with ROS arguments (they configure this process's node)."""
    if args.no_daemon or args.ros_arguments:
        return None
    if args.namespace is not None and namespace_problem(args.namespace):
        return None  # the direct path says what is wrong with it
    from contextros.cli.daemon.client import answer_for

    # Long enough for the client: it gives up 2 s after the timeout (10 s without one).
    longest = args.wait_manager + max(getattr(args, "timeout", 0.0), 10.0) + 2.0 + 5.0
    return answer_for(
        request | {"namespace": args.namespace, "wait_manager": args.wait_manager}, longest
    )


def _asked_directly(
    args: argparse.Namespace, request: dict[str, Any], teardown: ExitStack
) -> dict[str, Any]:
    """The daemon's answer to `request`, from a client node of the calling process (the
    command's child: see answered_in_child)."""
    if problem := _ros_problem(args):
        return problem
    try:
        client = _open_client(args, request["command"], teardown)
    except RosArgumentsError as error:
        return {"outcome": "usage", "message": str(error)}
    from contextros.cli.client_answers import client_answer

    return client_answer(client, request | {"wait_manager": args.wait_manager})


def _ros_problem(args: argparse.Namespace) -> dict[str, Any] | None:
    """A usage answer if rclpy or the messages cannot be imported (as main checks for the
    other ROS commands), else None."""
    from contextros.installation import ros_problem

    if problem := ros_problem():
        return {"outcome": "usage", "message": problem}
    return None


def _print_result(args: argparse.Namespace, on: list[str], result: dict[str, Any]) -> int:
    moved = _reordered(on, tuple(result["active"]), result["message"])
    if moved and result["success"]:
        print(
            f"contextros: warning: activation order {', '.join(on)} contradicts the declared "
            f"order ({moved}); the manager composed [{', '.join(result['active'])}] "
            "(last = outermost)",
            file=sys.stderr,
        )
    if args.json:
        print(json.dumps(result))
    else:
        layers = ", ".join(result["active"]) or "none"
        print(f"epoch {result['epoch']}: active [{layers}]")
        if result["success"] and result["message"].startswith("no change"):
            print(result["message"])
        elif result["success"] and (result["acknowledged"] or result["not_acknowledged"]):
            print(
                f"acknowledged by {len(result['acknowledged'])} node(s) "
                f"in {result['elapsed'] * 1000:.1f} ms"
            )
    if not result["success"]:
        # A failure reads as one on stderr, never as an acknowledgement on stdout.
        print(f"contextros: {result['message']}", file=sys.stderr)
        if result["acknowledged"] and not args.json:
            print(
                f"contextros: applied only by {', '.join(result['acknowledged'])}",
                file=sys.stderr,
            )
        return FAILED
    return 0


def _reordered(requested: list[str], active: tuple[str, ...], message: str) -> str:
    """Why the manager composed the requested layers in another order ("" if it did not):
    the declarations its answer names ('Rubble after Flooded')."""
    position = {name: index for index, name in enumerate(active)}
    present = [name for name in dict.fromkeys(requested) if name in position]
    if present == sorted(present, key=position.__getitem__):
        return ""
    from contextros.protocol.relations import ORDER_NOTE

    _, _, declared = message.partition(ORDER_NOTE)
    return declared or "declared with 'after'"


def run_status(args: argparse.Namespace) -> int:
    request = {"command": "status"}
    answer = _through_daemon(args, request)
    if answer is not None:
        return _show_status(args, answer)
    with answered_in_child(
        partial(_asked_directly, args, request), "nothing was changed"
    ) as answer:
        return _show_status(args, answer)


def _show_status(args: argparse.Namespace, answer: dict[str, Any]) -> int:
    if answer["outcome"] != "registry":
        print(f"contextros: {answer['message']}", file=sys.stderr)
        return _OUTCOME_STATUS.get(answer["outcome"], FAILED)
    registry = answer["registry"]
    for layer in registry["layers"]:
        # Known with no participant implementing it: only the manager's --layers files
        # declare it (docs/protocol.md).
        layer["declared_by_manager"] = not layer["implemented_by"]
    if args.json:
        print(json.dumps(registry, indent=2))
    else:
        print(_registry_as_text(registry))
    return 0


def _table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(cell)) for cell in column) for column in zip(header, *rows, strict=False)]
    lines = [header, ["-" * w for w in widths], *rows]
    return "\n".join(
        "  ".join(str(cell).ljust(w) for cell, w in zip(line, widths, strict=False)).rstrip()
        for line in lines
    )


def _active_cell(name: str, active: list[str], implied: dict[str, list[str]]) -> str:
    """`yes`, `implied by Flight` or nothing: the ACTIVE column of `contextros status`."""
    if name not in active:
        return ""
    return f"implied by {', '.join(implied[name])}" if implied.get(name) else "yes"


def _registry_as_text(data: dict[str, Any]) -> str:
    """`contextros status`'s tables, from `registry_to_dict`'s data."""
    implied = data.get("implied_by", {})
    active = listed_with_implied(data["active"], implied) or "none"
    by = f"{data['requester'] or '?'}: {data['reason'] or '-'}"
    parts = [f"epoch {data['epoch']}  active [{active}]  ({by})", ""]
    if data["recovering"]:
        parts[0] += "  - the manager is still recovering (listening to participants)"
    if data["declared_order"]:
        parts.insert(
            1,
            "composed in the declared order (last = outermost): "
            + ", ".join(data["declared_order"]),
        )
    layer_rows = [
        [
            layer["name"],
            _active_cell(layer["name"], data["active"], implied),
            layer["group"],
            ", ".join(layer["excludes"]),
            ", ".join(layer["requires"]),
            ", ".join(layer["after"]),
            ", ".join(layer.get("implies", ())),
            ", ".join(layer["implemented_by"])
            or (
                "(declared by the manager's layer file)" if layer.get("declared_by_manager") else ""
            ),
        ]
        for layer in data["layers"]
    ]
    header = ["LAYER", "ACTIVE", "GROUP", "EXCLUDES", "REQUIRES", "AFTER", "IMPLIES", "NODES"]
    parts.append(_table(header, layer_rows))
    parts.append("")
    node_rows = [
        [
            p["node"],
            str(p["applied_epoch"]),
            _node_state(p),
            "yes" if p["in_critical_section"] else "",
            f"{p['silent_for']:.1f} s",
            ", ".join(p["layers"]),
            ", ".join(p["hosted_nodes"]),
        ]
        for p in data["participants"]
    ]
    header = ["NODE", "EPOCH", "STATE", "CRITICAL", "LAST HEARD", "LAYERS", "ALSO FOR"]
    parts.append(_table(header, node_rows))
    for name in data["conflicts"]:
        parts += [
            "",
            f"CONFLICT: more than one live process is named {name} (state TWIN): each must "
            "acknowledge for itself; give every context node a unique name",
        ]
    refusing = [p for p in data["participants"] if _node_state(p) == "REFUSED"]
    if refusing:
        parts.append("")
        parts += [f"REFUSED: {p['node']} could not apply {p['error']}" for p in refusing]
    if data["dropped"]:
        parts += ["", f"dropped: {', '.join(data['dropped'])}"]
    if data["rules"]:
        parts += [
            "",
            _table(["RULE", "VALUE", "IN FORCE", "HOLD", "READS", "LAST"], _rule_rows(data)),
        ]
    if data["bindings"]:
        header, rows = binding_rows(data)
        parts += ["", actual_line(data), _table(header, rows), *drift_lines(data)]
    return "\n".join(parts)


def _node_state(participant: dict[str, Any]) -> str:
    """TWIN (a name clash), REFUSED (it could not apply a newer state: it said why), LAGS
    (not on the current epoch yet) or ok."""
    if participant["conflict"]:
        return "TWIN"
    if participant["failed_epoch"] > participant["applied_epoch"]:
        return "REFUSED"
    return "LAGS" if participant["lagging"] else "ok"


def _rule_rows(data: dict[str, Any]) -> list[list[str]]:
    rows = []
    for rule in data["rules"]:
        if rule["error"]:
            hold = f"OFF: {rule['error']}"
        elif rule["holding"]:
            hold = f"holding, {rule['hold_left']:.1f} of {rule['hold']:g} s left"
        elif rule["relaxed"]:
            hold = f"hysteresis {rule['hysteresis']:g} engaged"
        else:
            hold = "armed"
        last = f"{rule['last_firing']}: {rule['last_outcome']}" if rule["last_firing"] else "-"
        rows.append(
            [
                f"{rule['name']}: {rule['text']}",
                rule["value"],
                rule["settled"] or "-",
                hold,
                "; ".join(rule["readings"]),
                last,
            ]
        )
    return rows


def run_watch(args: argparse.Namespace) -> int:
    try:
        with ros_session(args):
            return _watch(args)
    except RosArgumentsError as error:
        return usage_error(error)


def _watch(args: argparse.Namespace) -> int:
    from contextros_interfaces.msg import LayerState, ParticipantStatus
    from rclpy.node import Node

    from contextros.cli.binding_status import DriftWatch
    from contextros.cli.exits import output_gone
    from contextros.cli.watching import SwitchWatch
    from contextros.ros import STATE_QOS, STATE_TOPIC, STATUS_QOS, STATUS_TOPIC, spin_nodes
    from contextros.ros.messages import binding_to_dict, declaration_from_msg, stamp_to_seconds
    from contextros.ros.registry_polling import RegistryPoller
    from contextros.ros.topics import QUERY_SERVICE

    node = Node(f"contextros_watch_{os.getpid()}")
    watch = SwitchWatch(started=time.time())
    drifts = DriftWatch()

    reader_gone: list[BrokenPipeError] = []

    def show(records: list[dict[str, Any]]) -> None:
        # (also called from a service answer's done callback, where rclpy would only warn
        # about an exception: the spin ends at once instead, and the error is raised then)
        try:
            for record in records:
                _print_watch(args.json, record)
        except BrokenPipeError as error:
            reader_gone.append(error)

    def on_state(msg: Any) -> None:
        show(
            watch.state(
                msg.epoch,
                list(msg.active_layers),
                msg.requester,
                msg.reason,
                published=stamp_to_seconds(msg.stamp),
                wall=time.time(),
                now=time.monotonic(),
            )
        )

    def on_status(msg: Any) -> None:
        watch.declared(declaration_from_msg(layer) for layer in msg.layers)
        show(
            watch.status(
                msg.node,
                msg.applied_epoch,
                msg.leaving,
                wall=time.time(),
                now=time.monotonic(),
                failed_epoch=msg.failed_epoch,
                error=msg.error,
                hosted=tuple(msg.hosted_nodes),
            )
        )

    def on_registry(answer: Any, asked: float) -> None:
        watch.declared(declaration_from_msg(layer) for layer in answer.layers)
        nodes = {p.node: tuple(p.hosted_nodes) for p in answer.participants}
        show(watch.registry(nodes, asked, wall=time.time()))
        show(drifts.bindings([binding_to_dict(b) for b in answer.bindings]))

    def on_tick() -> None:
        show(watch.tick(time.time()))
        if output_gone():
            raise BrokenPipeError("the standard output's reader went away")

    node.create_subscription(LayerState, STATE_TOPIC, on_state, STATE_QOS)
    node.create_subscription(ParticipantStatus, STATUS_TOPIC, on_status, STATUS_QOS)
    # The nodes the manager counts (its liveness bound, hosted nodes), twice a second.
    RegistryPoller(node, QUERY_SERVICE, on_registry, period=0.5)
    node.create_timer(0.2, on_tick)

    def finished() -> bool:
        if reader_gone:
            return True
        if not watch.finished(args.count, time.monotonic(), time.time()):
            return False
        show(watch.unsettled())
        return True

    spin_nodes([node], until=finished, timeout=args.duration, teardown_limit=TEARDOWN_LIMIT)
    if reader_gone:
        raise reader_gone[0]
    return 0


def _print_watch(as_json: bool, record: dict[str, Any]) -> None:
    if as_json:
        print(json.dumps(record), flush=True)
        return
    event = record["event"]
    epoch = f"epoch {record.get('epoch', 0):>6}"
    if event in ("drift", "drift-over"):
        line = _shown(drift_record_line(record))
    elif event == "node":
        line = f"node {_shown(record['node'])} is here"
    elif event == "node-left":
        gone = "dropped by the manager" if record.get("dropped") else "left"
        line = f"node {_shown(record['node'])} {gone}"
    elif event in ("current", "state"):
        active = listed_with_implied(record["active"], record.get("implied_by", {})) or "none"
        who = f"{record['requester'] or '?'}: {record['reason'] or '-'}"
        timing = (
            f"current state (replayed, published {record['age_s']:.1f} s ago)"
            if record["replayed"]
            else f"delivered in {record['delivery_ms']:.2f} ms"
        )
        line = f"{epoch}  [{_shown(active)}]  ({_shown(who)})  {timing}"
    elif event == "refused":  # as `contextros status` says it
        line = (
            f"{epoch}  REFUSED: {_shown(record['node'])} could not apply {_shown(record['error'])}"
        )
    elif event == "skipped":
        line = (
            f"{epoch}  SKIPPED: {_shown(record['node'])} went on to epoch "
            f"{record['went_to']} without applying it"
        )
    elif event == "not-applied":
        parts = [
            f"{verb} by {_shown(', '.join(record[key]))}"
            for verb, key in (("refused", "refused_by"), ("skipped", "skipped_by"))
            if record[key]
        ]
        parts.append(f"applied by {len(record['applied_by'])}")
        line = f"{epoch}  NOT applied by all {record['nodes']} live node(s): {'; '.join(parts)}"
    elif event == "unsettled":
        line = (
            f"{epoch}  NOT settled when the watch ended: no word from "
            f"{_shown(', '.join(record['pending']))} of {record['nodes']} live node(s)"
        )
    else:
        line = (
            f"{epoch}  applied by all {record['nodes']} live node(s) "
            f"{record['latency_ms']:.2f} ms after publication"
        )
    print(line, flush=True)


def _shown(text: str) -> str:
    """Text from the network as a terminal line shows it: no control characters."""
    return "".join(c if c.isprintable() else "?" for c in text)
