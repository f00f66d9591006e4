"""What the protocol state machines take in and give back: plain immutable values.

The rclpy adapter translates ROS messages to these and back; nothing here knows ROS, so
the same protocol could sit behind another transport or be driven by a test clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from contextros.protocol.relations import LayerDeclaration
from contextros.protocol.state import LayerState

# -- events ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class ParticipantReport:
    """A participant's status: who it is, what it implements, what it has applied."""

    node: str
    incarnation: str = ""
    layers: tuple[LayerDeclaration, ...] = ()
    applied_epoch: int = 0
    active: tuple[str, ...] = ()
    applied_manager_id: str = ""
    in_critical_section: bool = False
    pending_epoch: int = 0
    failed_epoch: int = 0
    error: str = ""
    leaving: bool = False
    # Other nodes of the participant's process it speaks for (the configuration is per process).
    hosted: tuple[str, ...] = ()


@dataclass(frozen=True)
class ActivationCommand:
    """A request to change the active layers; `request_id` lets the adapter route the reply."""

    request_id: int
    activate: tuple[str, ...] = ()
    deactivate: tuple[str, ...] = ()
    synchronous: bool = False
    timeout: float = 0.0  # seconds; 0 = the manager's default
    requester: str = ""
    reason: str = ""


@dataclass(frozen=True)
class ActivationResult:
    success: bool
    message: str
    epoch: int
    active: tuple[str, ...]
    acknowledged: tuple[str, ...] = ()
    not_acknowledged: tuple[str, ...] = ()
    elapsed: float = 0.0


# -- actions --------------------------------------------------------------------------------


@dataclass(frozen=True)
class PublishState:
    """Persist (when a state file is configured) and then broadcast this state."""

    state: LayerState


@dataclass(frozen=True)
class Reply:
    request_id: int
    result: ActivationResult


@dataclass(frozen=True)
class ParticipantJoined:
    node: str
    restarted: bool = False


@dataclass(frozen=True)
class ParticipantDropped:
    node: str
    reason: str


@dataclass(frozen=True)
class ParticipantConflict:
    """Two live processes report under one node name: their acknowledgements mix up."""

    node: str


@dataclass(frozen=True)
class ApplyState:
    """Participant side: make this state the node's decisive configuration (in its executor)."""

    state: LayerState


@dataclass(frozen=True)
class PublishStatus:
    """Participant side: send this report to the manager."""

    report: ParticipantReport


ManagerAction = PublishState | Reply | ParticipantJoined | ParticipantDropped | ParticipantConflict
ParticipantAction = ApplyState | PublishStatus
