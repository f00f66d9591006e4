"""The Layer manager protocol as pure state machines (no ROS, no I/O, time passed in).

`ManagerProtocol` and `ParticipantProtocol` take events and return actions; the rclpy
adapter in `contextros.ros` only translates messages and runs timers. See docs/protocol.md.
"""

from contextros.protocol.errors import ActivationFailed, ManagerError, StateFileError
from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ApplyState,
    ManagerAction,
    ManagerFound,
    ManagerLost,
    ParticipantAction,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    ParticipantReport,
    PublishHeartbeat,
    PublishProposal,
    PublishState,
    PublishStatus,
    Reply,
    ReportRejected,
    StateRejected,
)
from contextros.protocol.manager import (
    ManagerProtocol,
    ManagerSettings,
    ParticipantView,
    RegistryView,
)
from contextros.protocol.participant import (
    DEFAULT_HEARTBEAT_PERIOD,
    DEFAULT_MANAGER_TIMEOUT,
    LEAVE_REPEAT_AFTER,
    ParticipantProtocol,
)
from contextros.protocol.relations import (
    LayerDeclaration,
    merge_declarations,
    relation_violations,
)
from contextros.protocol.state import (
    INITIAL_STATE,
    MAX_EPOCH,
    KnownParticipant,
    LayerState,
    ManagerMemory,
)

__all__ = [
    "DEFAULT_HEARTBEAT_PERIOD",
    "DEFAULT_MANAGER_TIMEOUT",
    "INITIAL_STATE",
    "LEAVE_REPEAT_AFTER",
    "MAX_EPOCH",
    "ActivationCommand",
    "ActivationFailed",
    "ActivationResult",
    "ApplyState",
    "KnownParticipant",
    "LayerDeclaration",
    "LayerState",
    "ManagerAction",
    "ManagerError",
    "ManagerFound",
    "ManagerLost",
    "ManagerMemory",
    "ManagerProtocol",
    "ManagerSettings",
    "ParticipantAction",
    "ParticipantConflict",
    "ParticipantDropped",
    "ParticipantJoined",
    "ParticipantProtocol",
    "ParticipantReport",
    "ParticipantView",
    "PublishHeartbeat",
    "PublishProposal",
    "PublishState",
    "PublishStatus",
    "RegistryView",
    "Reply",
    "ReportRejected",
    "StateFileError",
    "StateRejected",
    "merge_declarations",
    "relation_violations",
]
