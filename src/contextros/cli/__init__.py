"""The `contextros` command: the user's tool (there is no `ros2` CLI on pip installs)."""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Sequence

from contextros import __version__
from contextros.cli import daemon_commands, exits, language_commands, observe_commands, ros_commands
from contextros.cli.answered_in_child import INTERRUPTED
from contextros.cli.ros_arguments import split_ros_arguments
from contextros.cli.ros_commands import USAGE
from contextros.installation import cmake_package_prefixes, ros_problem

# The commands that run until stopped: SIGINT or SIGTERM is their normal end (status 0).
RUN_UNTIL_STOPPED = ("manager", "watch", "record", "dashboard")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="contextros",
        description="Context-oriented programming for ROS 2: compile and check layer files, "
        "run the Layer manager, switch layers across nodes.",
    )
    parser.add_argument("--version", action="version", version=f"contextros {__version__}")
    parser.add_argument(
        "--cmake-prefix",
        action="store_true",
        help="print the prefix holding ContextROS's CMake package, for a C++ project's "
        "CMAKE_PREFIX_PATH (find_package(contextros CONFIG REQUIRED))",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    language_commands.register(commands)
    observe_commands.register_offline(commands)
    offline = set(commands.choices)
    ros_commands.register(commands)
    observe_commands.register_ros(commands, ros_commands.add_namespace_option)
    daemon_commands.register(commands)
    # ROS is checked before these run (see main); the daemon's commands check it only when
    # they ask the manager themselves (importing rclpy to check would cost most of a run).
    for name in set(commands.choices) - offline - set(ros_commands.DAEMON_SERVED):
        commands.choices[name].set_defaults(needs_ros=True)
    for name in RUN_UNTIL_STOPPED:
        commands.choices[name].set_defaults(runs_until_stopped=True)
    return parser


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser's subcommands by name (`rules replay` for nested ones)."""
    found: dict[str, argparse.ArgumentParser] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, subparser in action.choices.items():
                deeper = subcommands(subparser)
                found |= {f"{name} {verb}": p for verb, p in deeper.items()} or {name: subparser}
    return found


def options_after_command(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """`argv` with the options given before the command moved after it, where argparse
    looks for them: `contextros --namespace /robot1 status` is `contextros status
    --namespace /robot1` (the parser's own options, --version, --help, stay first)."""
    commands = subcommands(parser)
    names = {name.split()[0] for name in commands}
    own = {option for action in parser._actions for option in action.option_strings}
    # Options taking a value: a value that is a command's name (`--requester status`) is
    # not the command.
    valued = {
        option
        for command_parser in (parser, *commands.values())
        for action in command_parser._actions
        if action.nargs != 0
        for option in action.option_strings
    }
    words = list(argv)
    command, index = None, 0
    while index < len(words):
        word = words[index]
        if word in names:
            command = index
            break
        index += 2 if word in valued else 1
    if command is None:
        return words
    before = words[:command]
    kept = [word for word in before if word in own]
    moved = [word for word in before if word not in own]
    rest = words[command:]
    end = rest.index("--") if "--" in rest else len(rest)
    return [*kept, *rest[:end], *moved, *rest[end:]]


def main(argv: Sequence[str] | None = None) -> int:
    """Run a command; its exit status (docs/cli.md, "Exit statuses")."""
    previous = exits.stop_on_signals()
    args = argparse.Namespace()
    try:
        try:
            status = _run(args, sys.argv[1:] if argv is None else argv)
        except SystemExit as done:  # argparse's --help, --version and usage errors
            status = done.code if isinstance(done.code, int) else int(done.code is not None)
        sys.stdout.flush()  # here, where a reader gone away is seen, not at exit
        if exits.received is not None:  # whatever the interruption made of its result
            return _stopped_status(args, exits.received)
        return status
    except BrokenPipeError:
        return exits.output_closed()
    except BaseException as error:
        stop = exits.stopped_under(error)
        if stop is None and not exits.ros_context_shut_by_signal:
            raise
        signum = stop.signum if stop is not None else exits.received or signal.SIGINT
        return _stopped_status(args, signum)
    finally:
        exits.after_command(None if argv is None else previous)


def _stopped_status(args: argparse.Namespace, signum: int) -> int:
    """0 for a command that runs until stopped, else the shell's status for the signal."""
    until_stopped = getattr(args, "runs_until_stopped", False)
    if callable(until_stopped):  # it depends on the options
        until_stopped = until_stopped(args)
    return 0 if until_stopped else 128 + signum


def _run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    # numpy, which rclpy imports, otherwise starts an OpenBLAS thread per core that spins
    # for a while: 0.1 s of CPU per ROS process here; no command needs threaded algebra.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    parser = build_parser()
    # Standard ROS arguments (`--ros-args -r __ns:=/robot1 ...`) go to rclpy, untouched.
    own, ros_arguments = split_ros_arguments(argv)
    parser.parse_args(options_after_command(parser, own), namespace=args)
    args.ros_arguments = ros_arguments
    if args.cmake_prefix:
        return _print_cmake_prefix()
    if args.command is None:
        parser.print_help()
        return 0
    if getattr(args, "needs_ros", False) and (problem := ros_problem()):
        print(f"contextros {args.command}: {problem}", file=sys.stderr)
        return USAGE
    status: int = args.run(args)
    if status == INTERRUPTED:  # the command's own client said so
        return exits.interrupted_status()
    return status


def _print_cmake_prefix() -> int:
    prefixes = cmake_package_prefixes()
    if not prefixes:
        print(
            f"contextros: no installed C++ package (share/contextros/cmake) in {sys.prefix} or "
            "CMAKE_PREFIX_PATH/AMENT_PREFIX_PATH; it comes with the contextros wheel or a "
            "colcon build of cpp/ (see docs/install.md)",
            file=sys.stderr,
        )
        return USAGE
    print(prefixes[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
