"""The `contextros` command: the user's tool (there is no `ros2` CLI on pip installs)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from contextros import __version__
from contextros.cli import language_commands, ros_commands
from contextros.cli.ros_arguments import split_ros_arguments


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="contextros",
        description="Context-oriented programming for ROS 2: compile and check layer files, "
        "run the Layer manager, switch layers across nodes.",
    )
    parser.add_argument("--version", action="version", version=f"contextros {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    language_commands.register(commands)
    ros_commands.register(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    # Standard ROS arguments (`--ros-args -r __ns:=/robot1 ...`) go to rclpy, untouched.
    own, ros_arguments = split_ros_arguments(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(own)
    args.ros_arguments = ros_arguments
    if args.command is None:
        parser.print_help()
        return 0
    status: int = args.run(args)
    return status


if __name__ == "__main__":
    sys.exit(main())
