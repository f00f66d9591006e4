"""ROS arguments on the `contextros` command line: `--ros-args ... [--]` and `--namespace`.

Every ROS executable takes the standard arguments (`--ros-args -r __ns:=/robot1 -r
__node:=name -p ...`); argparse does not know them, so they are taken out of the command
line before parsing and handed to `rclpy.init` untouched. `--namespace NS` is the short form
of `--ros-args -r __ns:=NS`. Kept free of rclpy, so `contextros --help` works without ROS.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

ROS_ARGS = "--ros-args"
END_OF_ROS_ARGS = "--"

# A ROS namespace: absolute, tokens of letters, digits and underscores not starting with a
# digit, no empty token (rcl's rules, checked here so the message names the option).
_NAMESPACE = re.compile(r"^/([A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*)?$")


def split_ros_arguments(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """Split `argv` into this program's own arguments and the ROS arguments.

    The ROS arguments are returned with their `--ros-args` markers (as rclpy expects them);
    a `--` ends a ROS section, and several sections may appear.
    """
    own: list[str] = []
    ros: list[str] = []
    inside = False
    for word in argv:
        if word == ROS_ARGS:
            inside = True
            ros.append(word)
        elif inside and word == END_OF_ROS_ARGS:
            inside = False
            ros.append(word)
        elif inside:
            ros.append(word)
        else:
            own.append(word)
    return own, ros


def namespace_problem(namespace: str) -> str | None:
    """Why `namespace` is not a usable ROS namespace, or None."""
    if _NAMESPACE.match(namespace):
        return None
    return (
        f"--namespace {namespace!r} is not a ROS namespace: it must start with '/' and "
        "consist of names of letters, digits and underscores separated by '/' "
        "(e.g. /robot1)"
    )


def rclpy_arguments(program: str, ros_arguments: Sequence[str], namespace: str | None) -> list[str]:
    """The argument list for `rclpy.init(args=...)`: `--namespace` as a remapping, then the
    ROS arguments (rcl applies the first matching remapping rule, so the option wins)."""
    arguments = [program]
    if namespace is not None:
        arguments += [ROS_ARGS, "-r", f"__ns:={namespace}", END_OF_ROS_ARGS]
    return [*arguments, *ros_arguments]
