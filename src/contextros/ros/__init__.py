"""The ROS 2 adapter: the Layer manager node, context nodes, the activation client.

Thin glue around `contextros.protocol` (all decisions live there); importing this
package needs rclpy and the built `contextros_interfaces` package.
"""

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

__all__ = [
    "ACTIVATE_SERVICE",
    "QUERY_SERVICE",
    "STATE_QOS",
    "STATE_TOPIC",
    "STATUS_QOS",
    "STATUS_TOPIC",
    "ContextNode",
    "ContextParticipant",
    "LayerClient",
    "LayerManagerNode",
    "StateFile",
    "declaration_of",
    "spin_nodes",
]
