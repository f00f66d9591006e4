"""Names and QoS of the protocol's topics and services (documented in docs/protocol.md)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Relative names: ROS resolves them against the node's namespace, so a manager and nodes
# started in /robot1 (`--ros-args -r __ns:=/robot1`) use /robot1/contextros/state and form
# one system, /robot2 another, in one domain. The default namespace gives /contextros/....
# Standard remapping arguments (`-r contextros/state:=...`) apply to these names too.
NAMESPACE = "contextros"
STATE_TOPIC = f"{NAMESPACE}/state"
HEARTBEAT_TOPIC = f"{NAMESPACE}/heartbeat"
PROPOSAL_TOPIC = f"{NAMESPACE}/proposal"
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

# The manager's heartbeat: the current state again, shortly after each change and then
# periodically. Best effort: on a lossy link a reliable sample waits behind retransmissions
# (seconds, measured), while the next repeat of a lost one comes within a heartbeat.
HEARTBEAT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

# Proposals of atomic activations: repeated by the manager until the vote ends, so best
# effort as the heartbeat (a participant votes once per proposal).
PROPOSAL_QOS = HEARTBEAT_QOS

# Participants' reports. Each one is complete (applied epoch, layers...) and repeated (shortly
# after a change, then by the heartbeat), so a lost report costs one repeat, never more:
# best effort, as a reliable writer blocked the newer reports behind a lost one for 1.4 s
# median, 11 s at worst, at 30% loss (docs/protocol.md). The depth absorbs bursts of acks.
STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

# The activation service, both sides. Fast DDS (rmw_fastrtps 9) hands every reply of a
# service to every client's reply reader and drops those for other clients only when a
# client takes one: with the default depth (10), a client that did not take for a moment
# lost its own replies under other clients' ones (3 of 1800 in a storm from 3 clients).
# The manager's request reader holds requests from every client the same way. A depth of
# max_waiting_commands' default keeps a burst the manager can still answer, if refusing.
ACTIVATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

# The query service is polled by `status`, dashboards and scripts at once: the same holds.
QUERY_QOS = ACTIVATE_QOS
