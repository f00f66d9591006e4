"""Seeing and replaying the context: `record`, `rules replay` and `dashboard`."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from contextros.cli.option_types import PORT, Seconds
from contextros.errors import LayerError

USAGE = 2
DIFFERENT = 1  # `rules replay --strict`: the replay differs from the recording
# rules.replay.TIME_TOLERANCE (importing it here would import the protocol for every command).
TIME_TOLERANCE = 0.25
# The manager's node name (contextros.ros.topics.MANAGER_NODE_NAME, which imports rclpy).
MANAGER_NODE = "contextros_manager"


def register_offline(commands: Any) -> None:
    """`rules replay`: no ROS needed (the recording is decoded from its own schemas)."""
    rules = commands.add_parser("rules", help="work with context rules offline")
    verbs = rules.add_subparsers(dest="rules_command", metavar="VERB", required=True)
    replay = verbs.add_parser(
        "replay",
        help="evaluate rules over a recording (MCAP) as the manager would: every switch, "
        "with its time and cause, and a PNG timeline",
    )
    replay.add_argument("recording", type=Path, metavar="IN.mcap")
    replay.add_argument(
        "--rules", nargs="+", required=True, metavar="FILE.layers", help="the rules to try"
    )
    replay.add_argument("--plot", type=Path, metavar="OUT.png", help="write the timeline here")
    replay.add_argument("--json", action="store_true", help="print JSON instead of lines")
    replay.add_argument(
        "--namespace",
        default="/",
        metavar="NS",
        help="the manager's namespace in the recording (default /)",
    )
    replay.add_argument(
        "--tolerance",
        type=Seconds(),
        default=TIME_TOLERANCE,
        metavar="S",
        help="a replayed state further than this from the recorded one is a difference "
        f"(default {TIME_TOLERANCE:g} s)",
    )
    replay.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 when the replay differs from the states recorded live (layers, order, "
        "time beyond --tolerance)",
    )
    replay.set_defaults(run=run_replay)

    repair = commands.add_parser(
        "repair",
        help="make a recording whose recorder was killed whole again: every readable "
        "message into a complete MCAP file (as ros2 bag reindex)",
    )
    repair.add_argument("recording", type=Path, metavar="IN.mcap")
    repair.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="OUT.mcap",
        help="where to write the repaired copy (default: IN.repaired.mcap beside it)",
    )
    repair.add_argument(
        "--force", action="store_true", help="replace OUT.mcap if it exists (refused otherwise)"
    )
    repair.set_defaults(run=run_repair)


def register_ros(commands: Any, add_namespace_option: Any) -> None:
    record = commands.add_parser(
        "record",
        help="record the protocol's topics and the rules' input topics to MCAP "
        "(rosbag2's format: ros2 bag and Foxglove open it)",
    )
    record.add_argument("output", type=Path, metavar="OUT.mcap")
    record.add_argument(
        "--rules",
        nargs="+",
        default=[],
        metavar="FILE.layers",
        help="also record the topics these files' rules read",
    )
    record.add_argument(
        "--topic", nargs="+", default=[], metavar="TOPIC", help="also record these topics"
    )
    record.add_argument(
        "--duration", type=Seconds(positive=True), metavar="S", help="stop after S seconds"
    )
    add_namespace_option(record)
    record.set_defaults(run=run_record)

    dashboard = commands.add_parser(
        "dashboard",
        help="serve a live web page of the context: layers, switches, nodes, rules, bindings",
    )
    dashboard.add_argument(
        "--namespace",
        dest="robots",
        nargs="+",
        default=["/"],
        metavar="NS",
        help="the robots' namespaces, one section each (default /)",
    )
    dashboard.add_argument(
        "--host",
        default="127.0.0.1",
        help="the address to listen on (default 127.0.0.1: this machine only; see "
        "docs/observability.md before exposing it)",
    )
    dashboard.add_argument(
        "--port", type=PORT, default=8080, help="the port (default 8080; 0: any free one)"
    )
    dashboard.set_defaults(run=run_dashboard)


# -- record -----------------------------------------------------------------------------------


def run_record(args: argparse.Namespace) -> int:
    from contextros.cli.ros_commands import RosArgumentsError, ros_session, usage_error

    try:
        from mcap.writer import Writer  # noqa: F401 - only whether it is there
    except ImportError as error:
        return _missing("record", error)
    selected = _record_topics(args)
    if selected is None:
        return USAGE
    try:
        with ros_session(args):
            return _record(args, *selected)
    except RosArgumentsError as error:
        return usage_error(error)


def _record_topics(args: argparse.Namespace) -> tuple[dict[str, Any], Any] | None:
    """The topics to record, and the rules whose graph conditions' nodes to follow."""
    from contextros.ros.recorder import PROTOCOL_TOPICS, rule_topics
    from contextros.ros.rules import RULE_QOS

    topics: dict[str, Any] = dict(PROTOCOL_TOPICS)
    rules: tuple[Any, ...] = ()
    if args.rules:
        from contextros.rules import RuleSet

        try:
            rules = RuleSet.from_files(args.rules).rules
        except LayerError as error:
            print(f"contextros record: the layer files have errors:\n{error}", file=sys.stderr)
            return None
        for topic, qos in rule_topics(rules).items():
            topics.setdefault(_as_manager_topic(topic), qos)
    for topic in args.topic:
        topics.setdefault(topic, RULE_QOS)
    return topics, rules


def _as_manager_topic(topic: str) -> str:
    """A rule's topic as the manager resolves it: `~/x` is private to the manager node."""
    return f"{MANAGER_NODE}/{topic[2:]}" if topic.startswith("~/") else topic


def _record(args: argparse.Namespace, topics: dict[str, Any], rules: Any) -> int:
    from rclpy.node import Node

    from contextros.cli.ros_commands import TEARDOWN_LIMIT
    from contextros.ros import spin_nodes
    from contextros.ros.recorder import Recorder, TopicNameError

    node = Node(f"contextros_record_{os.getpid()}")
    try:
        recorder = Recorder(node, args.output, topics, graph_rules=rules)
    except TopicNameError as error:
        print(f"contextros record: {error}", file=sys.stderr)
        return USAGE
    except OSError as error:
        print(f"contextros record: cannot write {args.output}: {error.strerror}", file=sys.stderr)
        return USAGE
    print(f"recording to {args.output} (Ctrl-C stops)", file=sys.stderr, flush=True)
    try:  # the file is complete before the node's teardown, whatever that does
        spin_nodes(
            [node],
            timeout=args.duration,
            before_teardown=recorder.finish,
            teardown_limit=TEARDOWN_LIMIT,
        )
    finally:
        recorder.finish()
    counts = ", ".join(f"{topic}: {n}" for topic, n in sorted(recorder.counts.items()))
    print(f"recorded {sum(recorder.counts.values())} messages to {args.output} ({counts})")
    if recorder.waiting_for:
        print(f"never seen on the graph: {', '.join(recorder.waiting_for)}", file=sys.stderr)
    return 0


# -- dashboard ------------------------------------------------------------------------------


def run_dashboard(args: argparse.Namespace) -> int:
    from contextros.cli.ros_arguments import namespace_problem
    from contextros.cli.ros_commands import RosArgumentsError, ros_session, usage_error

    try:
        import aiohttp  # noqa: F401 - only whether it is there
    except ImportError as error:
        return _missing("dashboard", error)
    for namespace in args.robots:
        if problem := namespace_problem(namespace):
            print(f"contextros dashboard: {problem}", file=sys.stderr)
            return USAGE
    try:
        with ros_session(args):
            return _dashboard(args)
    except RosArgumentsError as error:
        return usage_error(error)


def _dashboard(args: argparse.Namespace) -> int:
    from contextros.cli.ros_commands import TEARDOWN_LIMIT
    from contextros.dashboard.model import DashboardModel
    from contextros.dashboard.server import DashboardServer, serve
    from contextros.ros.dashboard_node import DashboardNode
    from contextros.ros.spinning import bounded_teardown, spinning_in_thread

    model = DashboardModel(args.robots)
    server = DashboardServer(model)
    model.on_change = server.notify
    node = DashboardNode(model, args.robots)

    def ready(port: int) -> None:
        host = f"[{args.host}]" if ":" in args.host else args.host
        print(f"dashboard on http://{host}:{port}/ (Ctrl-C stops)", flush=True)

    try:
        with spinning_in_thread(node, "contextros-dashboard-ros", TEARDOWN_LIMIT):
            serve(server, args.host, args.port, ready)
    except BrokenPipeError:  # the URL's reader went away: main's to end it
        raise
    except OSError as error:
        print(
            f"contextros dashboard: cannot listen on {args.host}:{args.port}: {error}",
            file=sys.stderr,
        )
        return USAGE
    finally:
        with bounded_teardown(TEARDOWN_LIMIT):
            node.destroy_node()
    return 0


# -- rules replay ---------------------------------------------------------------------------


def run_replay(args: argparse.Namespace) -> int:
    from contextros.cli.ros_arguments import namespace_problem
    from contextros.recording import RecordingError
    from contextros.rules import RuleSet
    from contextros.rules.replay import compare

    if problem := namespace_problem(args.namespace):
        print(f"contextros rules replay: {problem}", file=sys.stderr)
        return USAGE
    if args.plot:
        try:
            import matplotlib  # noqa: F401 - only whether it is there
        except ImportError as error:
            return _missing("rules replay --plot", error)
        if problem := _plot_problem(args.plot):
            print(f"contextros rules replay: --plot {args.plot}: {problem}", file=sys.stderr)
            return USAGE
    try:
        rules = RuleSet.from_files(args.rules)
    except LayerError as error:
        print(f"contextros rules replay: the rules have errors:\n{error}", file=sys.stderr)
        return USAGE
    try:
        replayed = _replay(args, rules)
    except RecordingError as error:
        print(f"contextros rules replay: {error}", file=sys.stderr)
        return USAGE
    if replayed is None:
        return USAGE
    result, recorded, start, end, damage, live = replayed
    # None: the recording holds no state of a live manager, nothing to compare with.
    differences = (
        compare(result, recorded, rules, start=start, tolerance=args.tolerance) if live else None
    )
    if args.plot:
        from contextros.recording.timeline import write_timeline

        write_timeline(result, rules, start, end, args.plot)
    if args.json:
        report = _replay_json(result, recorded, differences, start, damage)
        print(json.dumps(report, indent=2))
    else:
        _print_replay(result, recorded, differences, start, end, args)
    return DIFFERENT if args.strict and differences else 0


def _plot_problem(path: Path) -> str:
    """Why the timeline cannot be written to `path` ('' if it can), known before replaying."""
    folder = path.parent
    if path.is_dir():
        return "is a directory"
    if not folder.is_dir():
        return f"no directory {folder}"
    if not os.access(folder, os.W_OK):
        return f"the directory {folder} is not writable"
    return ""


def _resolve(namespace: str, topic: str) -> str:
    if topic.startswith("/"):
        return topic
    base = namespace.rstrip("/")
    if topic.startswith("~/"):
        return f"{base}/{MANAGER_NODE}/{topic[2:]}"
    return f"{base}/{topic}"


def _replay(args: argparse.Namespace, rules: Any) -> Any:
    from contextros.language.declarations import declarations_from_files
    from contextros.protocol.manager import RECOVERY_REQUESTER
    from contextros.recording import read_recording
    from contextros.recording.reader import Damage
    from contextros.rules.graph import answers_each_event
    from contextros.rules.replay import RecordedState, RuleReplay, declaration_from_recorded

    namespace = args.namespace
    by_topic = {_resolve(namespace, topic): topic for topic in rules.topics()}
    state_topic = _resolve(namespace, "contextros/state")
    status_topic = _resolve(namespace, "contextros/status")
    notes: list[str] = []
    damages: list[Damage] = []
    # First pass: what the participants declared, the first state, the time span.
    declarations = []
    first_state = None
    start = end = None
    seen: set[str] = set()
    answered = False  # the nodes' answers to each graph event are recorded: they are the values
    for item in read_recording(args.recording, note=notes.append, truncated=damages.append):
        start = item.time if start is None else start
        end = item.time
        seen.add(item.topic)
        answered = answered or answers_each_event(item.topic, item.message)
        if item.topic == status_topic:
            declarations += [declaration_from_recorded(i) for i in item.message.layers]
        elif item.topic == state_topic and first_state is None:
            first_state = item.message
    for damage in damages:  # a recorder killed: what it wrote before is replayed
        print(
            f"warning: {damage}; replaying the {damage.messages} messages before it "
            f"(`contextros repair {args.recording}` writes a whole copy)",
            file=sys.stderr,
        )
    if start is None or end is None:
        print(f"contextros rules replay: {args.recording} holds no messages", file=sys.stderr)
        return None
    missing = sorted(set(by_topic) - seen)
    for topic in missing:
        notes.append(f"no message on {topic} in the recording: the rules reading it never act")
    active = tuple(first_state.active_layers) if first_state is not None else ()
    replay = RuleReplay(
        rules,
        declarations,
        layer_files=declarations_from_files(args.rules),
        start=start,
        active=active,
        namespace=namespace,
        graph_events=not answered,
    )
    recorded = []
    seen_first = False
    for item in read_recording(args.recording, truncated=lambda damage: None):
        if item.topic in by_topic:
            replay.message(item.time, by_topic[item.topic], item.message)
        elif replay.graph_message(item.time, item.topic, item.message):
            pass  # a lifecycle state or parameter the rules read
        elif item.topic == state_topic:
            state = item.message
            requester = str(state.requester)
            if not seen_first:
                seen_first = True  # the state the recording began in: already in place
                continue
            active = tuple(state.active_layers)
            recorded.append(RecordedState(item.time, int(state.epoch), active, requester))
            if not requester.startswith("rule ") and requester != RECOVERY_REQUESTER:
                replay.manual(item.time, active, requester, str(state.reason))
    result = replay.finish(end)
    result.notes[:0] = notes
    live = first_state is not None
    return result, recorded, start, end, damages[0] if damages else None, live


def _replay_json(
    result: Any, recorded: list[Any], differences: list[Any] | None, start: float, damage: Any
) -> dict[str, Any]:
    return {
        "switches": [
            {
                "time": round(s.time - start, 4),
                "epoch": s.epoch,
                "active": list(s.active),
                "requester": s.requester,
                "reason": s.reason,
            }
            for s in result.switches
        ],
        "refusals": [
            {"time": round(r.time - start, 4), "rule": r.rule, "asked": r.asked, "why": r.message}
            for r in result.refusals
        ],
        "recorded": [
            {
                "time": round(s.time - start, 4),
                "epoch": s.epoch,
                "active": list(s.active),
                "requester": s.requester,
            }
            for s in recorded
        ],
        # null: the recording holds no state of a live manager to compare with
        "differences": None
        if differences is None
        else [
            {"kind": d.kind, "time": round(d.time - start, 4), "text": d.text} for d in differences
        ],
        "truncated": None
        if damage is None
        else {
            "file": damage.path,
            "byte": damage.offset,
            "what": damage.what,
            "messages_before": damage.messages,
        },
        "first_inputs": {topic: round(t - start, 4) for topic, t in result.first_inputs.items()},
        "notes": result.notes,
    }


def _print_replay(
    result: Any,
    recorded: list[Any],
    differences: list[Any] | None,
    start: float,
    end: float,
    args: argparse.Namespace,
) -> None:
    """The switches in time order, then how they compare with the recorded states
    (`differences` None: the recording holds no state of a live manager)."""
    for note in result.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"{args.recording}: {end - start:.1f} s replayed through {', '.join(args.rules)}")
    events = [(s.time, f"[{', '.join(s.active) or 'none'}]  {s.cause}") for s in result.switches]
    events += [(r.time, f"rule {r.rule} could not {r.asked}: {r.message}") for r in result.refusals]
    for at, text in sorted(events, key=lambda event: event[0]):
        print(f"{at - start:9.3f} s  {text}")
    by_rules = sum(1 for s in recorded if s.requester.startswith("rule "))
    made = sum(1 for s in result.switches if s.requester.startswith("rule "))
    print(f"{made} switches by these rules; the recording has {by_rules} made by the live rules")
    states = f"{len(recorded)} state{'s' if len(recorded) != 1 else ''} recorded live"
    if differences is None:
        topic = _resolve(args.namespace, "contextros/state")
        print(f"no state of a live manager on {topic} in the recording: nothing to compare")
    elif differences:
        count = len(differences)
        print(f"{count} difference{'s' if count != 1 else ''} from the {states}:")
        for difference in differences:
            print(f"  {difference.kind}: {difference.text}")
    else:
        print(
            f"no difference from the {states}: the same layers in the same order, "
            f"each within {args.tolerance:g} s"
        )
    if args.plot:
        print(f"timeline: {args.plot}")


# -- repair ---------------------------------------------------------------------------------


def run_repair(args: argparse.Namespace) -> int:
    from contextros.recording import RecordingError
    from contextros.recording.repair import repair_recording

    source: Path = args.recording
    output: Path = args.output or source.with_name(f"{source.stem}.repaired.mcap")
    try:
        repair = repair_recording(source, output, replace=args.force)
    except RecordingError as error:
        print(f"contextros repair: {error}", file=sys.stderr)
        return USAGE
    if repair.damage is not None:
        print(f"{repair.damage}: copied what came before it", file=sys.stderr)
    elif repair.complete:
        print(f"{source} was complete already: copied as it was", file=sys.stderr)
    span = (
        f", {repair.end - repair.start:.1f} s"
        if repair.start is not None and repair.end is not None
        else ""
    )
    topics = ", ".join(f"{topic}: {n}" for topic, n in sorted(repair.topics.items()))
    print(
        f"repaired {repair.messages} messages{span} to {output}"
        + (f" ({topics})" if topics else "")
    )
    return 0


def _missing(command: str, error: ImportError) -> int:
    print(
        f"contextros {command}: needs the observability packages ({error.name} is missing): "
        "pip install 'contextros[observe]'",
        file=sys.stderr,
    )
    return USAGE
