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
    ParticipantAction,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    ParticipantReport,
    PublishState,
    PublishStatus,
    Reply,
)
from contextros.protocol.manager import (
    ManagerProtocol,
    ManagerSettings,
    ParticipantView,
    RegistryView,
)
from contextros.protocol.participant import DEFAULT_HEARTBEAT_PERIOD, ParticipantProtocol
from contextros.protocol.relations import (
    LayerDeclaration,
    merge_declarations,
    relation_violations,
)
from contextros.protocol.state import INITIAL_STATE, LayerState

__all__ = [
    "DEFAULT_HEARTBEAT_PERIOD",
    "INITIAL_STATE",
    "ActivationCommand",
    "ActivationFailed",
    "ActivationResult",
    "ApplyState",
    "LayerDeclaration",
    "LayerState",
    "ManagerAction",
    "ManagerError",
    "ManagerProtocol",
    "ManagerSettings",
    "ParticipantAction",
    "ParticipantConflict",
    "ParticipantDropped",
    "ParticipantJoined",
    "ParticipantProtocol",
    "ParticipantReport",
    "ParticipantView",
    "PublishState",
    "PublishStatus",
    "RegistryView",
    "Reply",
    "StateFileError",
    "merge_declarations",
    "relation_violations",
]
