"""Whether this Python can run the ROS 2 part, and what to install when it cannot.

Checked before any ROS command runs and when a ROS name is first imported from
`contextros.ros`, so a missing piece is one clear sentence instead of a traceback. Importing
this module imports nothing of ROS.
"""

from __future__ import annotations

import importlib

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


def require_ros() -> None:
    """Raise RosUnavailableError, saying what to install, unless the ROS part can run."""
    if problem := ros_problem():
        raise RosUnavailableError(problem)
