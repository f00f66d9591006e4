"""ROS processes of ContextROS load message type support without rosidl's code generator
(lean_imports), and the generator still loads when asked for."""

from __future__ import annotations

import subprocess
import sys

PROBE = """
import sys
import contextros.ros
from rclpy.serialization import serialize_message, deserialize_message
from contextros_interfaces.msg import LayerState
data = serialize_message(LayerState(epoch=7))
assert deserialize_message(data, LayerState).epoch == 7
print("generator loaded:", sorted(m for m in ("em", "lark", "rosidl_pycommon") if m in sys.modules))
import rosidl_generator_py as package
print("submodule:", package.import_type_support_impl.__name__)
from rosidl_generator_py import generate_py
print("generate_py:", callable(generate_py), "em" in sys.modules, package.__all__)
"""


def test_type_support_loads_without_the_generator_which_still_loads_on_demand() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "generator loaded: []",
        "submodule: rosidl_generator_py.import_type_support_impl",
        "generate_py: True True ['import_type_support', 'generate_py']",
    ]


def test_nothing_changes_when_the_package_was_loaded_before() -> None:
    probe = (
        "import rosidl_generator_py, sys\n"
        "from contextros.ros.lean_imports import skip_message_generator\n"
        "print(skip_message_generator(), 'em' in sys.modules)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True"]
