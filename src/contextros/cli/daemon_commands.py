"""`contextros daemon start|stop|status`: the helper that keeps commands fast (see
contextros.cli.daemon); commands start it themselves, these verbs are for scripts and
for looking."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from contextros.cli.ros_arguments import namespace_problem

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
        type=float,
        default=900.0,
        metavar="S",
        help="stop after S seconds without a command (default 900; 0: never)",
    )
    start.add_argument(
        "--warm-namespace",
        metavar="NS",
        help="discover the manager in this namespace at start (default /)",
    )
    start.set_defaults(run=run_start)
    stop = verbs.add_parser("stop", help="stop the daemon for this ROS environment")
    stop.set_defaults(run=run_stop)
    status = verbs.add_parser("status", help="say whether a daemon serves this environment")
    status.set_defaults(run=run_status)


def run_start(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client
    from contextros.cli.daemon.place import PlaceError, daemon_place

    if args.warm_namespace is not None and (problem := namespace_problem(args.warm_namespace)):
        print(f"contextros daemon: {problem}", file=sys.stderr)
        return USAGE
    if args.idle_timeout < 0:
        print("contextros daemon: --idle-timeout must be 0 or more", file=sys.stderr)
        return USAGE
    try:
        place = daemon_place()
    except PlaceError as error:
        print(f"contextros daemon: {error}", file=sys.stderr)
        return 1
    if args.foreground:
        from contextros.cli.daemon.server import serve

        return serve(place, args.idle_timeout, args.warm_namespace)
    pong = client.start(place, args.warm_namespace, args.idle_timeout)
    if pong is None:
        print(f"contextros daemon: it did not start; see {place.log}", file=sys.stderr)
        return 1
    print(f"daemon {pong['pid']} serves {place.socket}")
    return 0


def run_stop(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client
    from contextros.cli.daemon.place import PlaceError, daemon_place

    try:
        place = daemon_place()
    except PlaceError as error:
        print(f"contextros daemon: {error}", file=sys.stderr)
        return 1
    pid = client.stop(place)
    print(f"daemon {pid} stopped" if pid else "no daemon serves this environment")
    return 0


def run_status(args: argparse.Namespace) -> int:
    from contextros.cli.daemon import client
    from contextros.cli.daemon.place import PlaceError, daemon_place

    try:
        place = daemon_place()
    except PlaceError as error:
        print(f"contextros daemon: {error}", file=sys.stderr)
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
