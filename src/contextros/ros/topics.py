"""Names and QoS of the protocol's topics and services (documented in docs/protocol.md)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

NAMESPACE = "/contextros"
STATE_TOPIC = f"{NAMESPACE}/state"
STATUS_TOPIC = f"{NAMESPACE}/status"
ACTIVATE_SERVICE = f"{NAMESPACE}/activate"
QUERY_SERVICE = f"{NAMESPACE}/query"
MANAGER_NODE_NAME = "contextros_manager"

# Only the newest state matters (full snapshots), and a late joiner must get it at once.
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Every report counts (acknowledgements), but an old report is useless to a new manager:
# participants heartbeat, so volatile is enough. The depth absorbs bursts from many nodes.
STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
