"""`contextros daemon start|stop|status`: the helper that keeps commands fast (see
contextros.cli.daemon); commands start it themselves, these verbs are for scripts and
for looking."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, Any

from contextros.cli.option_types import Seconds
from contextros.cli.ros_arguments import namespace_problem

if TYPE_CHECKING:
    from contextros.cli.daemon.place import DaemonPlace

USAGE = 2


def register(commands: Any) -> None:
    daemon = commands.add_parser(
        "daemon",
        help="the background helper that answers activate/switch/status in milliseconds "
        "(started by the first command; set CONTEXTROS_NO_DAEMON=1 or pass --no-daemon "
        "to do without)",
    )
    verbs = daemon.add_subparsers(dest="daemon_command", metavar="VERB", required=True)
    start = verbs.add_parser("start", help="start the daemon for this ROS environment")
    start.add_argument(
        "--foreground", action="store_true", help="serve in this process, logging to stdout"
    )
    start.add_argument(
        "--idle-timeout",
        type=Seconds(),
        default=900.0,
        metavar="S",
        help="stop after S seconds without a command (default 900; 0: never)",
    )
    start.add_argument(
        "--warm-namespace",
        metavar="NS",
        help="discover the manager in this namespace at start (default /)",
    )
    # The key of the environment a command started the daemon for (it serves no other).
    start.add_argument("--expect-key", help=argparse.SUPPRESS)
    start.set_defaults(run=run_start)
    # Serving in the foreground, it runs until stopped (a signal's status: see cli.main).
    start.set_defaults(runs_until_stopped=lambda args: args.foreground)
    stop = verbs.add_parser("stop", help="stop the daemon for this ROS environment")
    stop.add_argument(
        "--all",
        action="store_true",
        help="stop every daemon of this user's directory, whatever its environment (one "
        "left by another domain, or by ContextROS's code before a change)",
    )
    stop.set_defaults(run=run_stop)
    status = verbs.add_parser("status", help="say whether a daemon serves this environment")
    status.set_defaults(run=run_status)


def run_start(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client

    if args.warm_namespace is not None and (problem := namespace_problem(args.warm_namespace)):
        print(f"contextros daemon: {problem}", file=sys.stderr)
        return USAGE
    if (place := _place()) is None:
        return 1
    if args.foreground:
        from contextros.cli.daemon.server import serve

        return serve(place, args.idle_timeout, args.warm_namespace, args.expect_key)
    running = client.ping(place)
    pong = running or client.start(place, args.warm_namespace, args.idle_timeout)
    if pong is None:
        print(f"contextros daemon: it did not start; see {place.log}", file=sys.stderr)
        return 1
    print(f"daemon {pong['pid']} serves {place.socket}")
    if running:
        print("(it was running: its idle timeout is unchanged; `contextros daemon stop` first)")
    return 0


def run_stop(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client

    if (place := _place()) is None:
        return 1
    from contextros.cli.daemon.place import places

    status = 0
    targets = places(place.directory) if args.all else [place]
    stopped = [(target, client.stop(target)) for target in targets]
    for target, outcome in stopped:
        if outcome is None:
            continue
        pid, gone = outcome
        if gone:
            print(f"daemon {pid} stopped ({target.socket})")
        else:
            print(f"contextros daemon: daemon {pid} did not stop in time", file=sys.stderr)
            status = 1
    if all(outcome is None for _, outcome in stopped):
        print("no daemon serves " + ("this user" if args.all else "this environment"))
    return status


def run_status(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client

    if (place := _place()) is None:
        return 1
    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    pong = client.ping(place)
    if pong is None:
        print(f"no daemon serves this environment (ROS_DOMAIN_ID={domain}, {place.socket})")
        return 1
    print(f"daemon {pong['pid']} serves {place.socket} (ROS_DOMAIN_ID={domain})")
    if not client.wanted():
        print(f"commands do not use it: {client.DISABLE_VARIABLE} is set")
    return 0


def _place() -> DaemonPlace | None:
    """The daemon's place for this environment, or None (said on stderr)."""
    from contextros.cli.daemon.place import PlaceError, daemon_place

    try:
        return daemon_place()
    except PlaceError as error:
        print(f"contextros daemon: {error}", file=sys.stderr)
        return None
