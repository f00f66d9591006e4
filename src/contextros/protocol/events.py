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
    # The participant has not heard the manager for its liveness bound.
    manager_lost: bool = False
    # Its vote on the atomic activation proposed as `vote_epoch` (0: none): yes, or why not.
    vote_epoch: int = 0
    vote_yes: bool = False
    vote_reason: str = ""
    # The manager that proposed it (a restarted manager may propose the same epoch again).
    vote_manager_id: str = ""


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
    # A synchronous command succeeds only if these nodes (participants or nodes they host)
    # and at least `expect_count` nodes in all applied the state; at least one always.
    expect_nodes: tuple[str, ...] = ()
    expect_count: int = 0
    # Two-phase: every target votes first; any veto, timeout or lost target aborts with
    # nothing changed anywhere, else the same epoch is committed everywhere.
    atomic: bool = False


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
class ReportRejected:
    """A status message failed validation and was ignored (log it; rate-limited)."""

    node: str
    problems: tuple[str, ...]


@dataclass(frozen=True)
class PublishHeartbeat:
    """Broadcast the current state again on the best-effort heartbeat topic: it repeats a
    new state shortly after its publication and tells participants the manager is alive.
    Epoch 0 means the manager has no state yet (still recovering)."""

    state: LayerState


@dataclass(frozen=True)
class PublishProposal:
    """Ask every participant to vote on this state (an atomic activation's first phase).
    Repeated while the vote is open; never applied by a participant."""

    state: LayerState


@dataclass(frozen=True)
class ApplyState:
    """Participant side: make this state the node's decisive configuration (in its executor)."""

    state: LayerState


@dataclass(frozen=True)
class PublishStatus:
    """Participant side: send this report to the manager."""

    report: ParticipantReport


@dataclass(frozen=True)
class StateRejected:
    """Participant side: a state message failed validation and was ignored (log it)."""

    problems: tuple[str, ...]


@dataclass(frozen=True)
class ManagerLost:
    """Participant side: the manager has not been heard for the liveness bound. The node
    keeps its configuration; handlers may fall back to a safe one."""

    silent_for: float


@dataclass(frozen=True)
class ManagerFound:
    """Participant side: a manager is heard again (or for the first time after a loss)."""

    manager_id: str


ManagerAction = (
    PublishState
    | PublishHeartbeat
    | PublishProposal
    | Reply
    | ParticipantJoined
    | ParticipantDropped
    | ParticipantConflict
    | ReportRejected
)
ParticipantAction = ApplyState | PublishStatus | StateRejected | ManagerLost | ManagerFound
# The manager's actions before which an adapter writes its memory (`ManagerMemory`) to its
# state file, if it changed: the same list for the ROS adapter and the explorer's model.
# (A reply too: a command that marks an implied layer as asked for publishes nothing.)
DURABLE = (PublishState, PublishProposal, ParticipantJoined, ParticipantDropped, Reply)
