"""What of ContextROS is installed here: the ROS 2 part (rclpy and the protocol's messages)
and the C++ package, with what to install when a piece is missing.

The ROS check runs before any ROS command and when a ROS name is first imported from
`contextros.ros`, so a missing piece is one clear sentence instead of a traceback. Importing
this module imports nothing of ROS.
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

from contextros.errors import LayerError

INSTALL_GUIDE = "docs/install.md"

_REMEDIES = {
    "rclpy": "install ROS 2: the pip wheels with `pip install 'contextros[ros]'`, or a system "
    "ROS 2 with `source /opt/ros/<distro>/setup.bash`",
    "contextros_interfaces": "they come with the contextros wheel (`pip install "
    "contextros-<version>-<tag>.whl`), with a colcon build of interfaces/ "
    "(`source install/setup.bash`), or with `make ros` in a clone",
}
_WHAT = {
    "rclpy": "rclpy (ROS 2's Python client library)",
    "contextros_interfaces": "the contextros_interfaces messages",
}


def ros_problem() -> str | None:
    """None when rclpy and the protocol's messages import, else what is missing and how to
    install it."""
    for module in ("rclpy", "contextros_interfaces.msg"):
        package = module.partition(".")[0]
        try:
            importlib.import_module(module)
        except ImportError as error:  # a missing module or a library that does not load
            return (
                f"{_WHAT[package]} cannot be imported ({error}); {_REMEDIES[package]} "
                f"(see {INSTALL_GUIDE})"
            )
    return None


class RosUnavailableError(LayerError, ImportError):
    """A name of `contextros.ros` was asked for where ROS 2 or the messages are missing."""


def cmake_package_prefixes() -> list[Path]:
    """The prefixes that hold an installed `contextros` CMake package: this Python's (the
    wheel installs it there), then those of CMAKE_PREFIX_PATH and AMENT_PREFIX_PATH
    (colcon)."""
    candidates = [Path(sys.prefix)]
    for variable in ("CMAKE_PREFIX_PATH", "AMENT_PREFIX_PATH"):
        entries = os.environ.get(variable, "").split(os.pathsep)
        candidates += [Path(entry) for entry in entries if entry]
    config = Path("share", "contextros", "cmake", "contextrosConfig.cmake")
    return [prefix for prefix in dict.fromkeys(candidates) if (prefix / config).is_file()]
