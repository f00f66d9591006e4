"""The ROS 2 adapter: the Layer manager node, context nodes, the activation client.

Thin glue around `contextros.protocol` (all decisions live there); importing this
package's names needs rclpy and the built `contextros_interfaces` package. Names are
imported lazily (PEP 562), each from its own module on first use: a client command
imports the client, not the manager and the participant.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from contextros._exports import lazy_exports
from contextros.installation import RosUnavailableError, ros_problem
from contextros.ros.lean_imports import skip_message_generator

# Before any message is used here: ROS processes start 0.16 s faster (see lean_imports).
skip_message_generator()

if TYPE_CHECKING:
    from contextros.protocol import ActivationFailed, ActivationResult, ManagerError
    from contextros.ros.client import LayerClient
    from contextros.ros.manager_node import LayerManagerNode, StateFile
    from contextros.ros.participant import ContextNode, ContextParticipant, declaration_of
    from contextros.ros.spinning import spin_nodes
    from contextros.ros.topics import (
        ACTIVATE_SERVICE,
        QUERY_SERVICE,
        STATE_QOS,
        STATE_TOPIC,
        STATUS_QOS,
        STATUS_TOPIC,
    )

_LAZY = {
    "ActivationFailed": "contextros.protocol.errors",
    "ActivationResult": "contextros.protocol.events",
    "ManagerError": "contextros.protocol.errors",
    "LayerClient": "contextros.ros.client",
    "LayerManagerNode": "contextros.ros.manager_node",
    "StateFile": "contextros.ros.manager_node",
    "ContextNode": "contextros.ros.participant",
    "ContextParticipant": "contextros.ros.participant",
    "declaration_of": "contextros.ros.participant",
    "spin_nodes": "contextros.ros.spinning",
    "ACTIVATE_SERVICE": "contextros.ros.topics",
    "QUERY_SERVICE": "contextros.ros.topics",
    "STATE_QOS": "contextros.ros.topics",
    "STATE_TOPIC": "contextros.ros.topics",
    "STATUS_QOS": "contextros.ros.topics",
    "STATUS_TOPIC": "contextros.ros.topics",
}


_lazy_getattr, __dir__ = lazy_exports(__name__, _LAZY, globals())


def __getattr__(name: str) -> Any:
    try:
        return _lazy_getattr(name)
    except ImportError as error:
        problem = ros_problem()
        raise RosUnavailableError(problem or str(error)) from error


__all__ = [
    "ACTIVATE_SERVICE",
    "QUERY_SERVICE",
    "STATE_QOS",
    "STATE_TOPIC",
    "STATUS_QOS",
    "STATUS_TOPIC",
    "ActivationFailed",
    "ActivationResult",
    "ContextNode",
    "ContextParticipant",
    "LayerClient",
    "LayerManagerNode",
    "ManagerError",
    "RosUnavailableError",
    "StateFile",
    "declaration_of",
    "spin_nodes",
]
