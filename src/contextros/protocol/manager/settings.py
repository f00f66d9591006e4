"""What a deployment tunes in the manager: time bounds, repeats and memory bounds."""

from __future__ import annotations

from dataclasses import dataclass

from contextros.protocol.relations import LayerDeclaration


@dataclass(frozen=True)
class ManagerSettings:
    # A participant heartbeats every 0.25 s by default, so 3 s of silence means it is gone:
    # twelve lost heartbeats in a row (5e-7 at 30% loss). With 2 s, a 30%-loss link with
    # delay jitter still saw a spurious drop in about 40 activations (benchmarks/lossy_link).
    liveness_timeout: float = 3.0
    # The participants' heartbeat period `liveness_timeout` is made for (twelve of them), and
    # the statuses per second the manager asks for at most when nothing changes: beyond
    # `status_rate * status_period` participants (250), the period it announces with every
    # state and heartbeat grows with their number, and the liveness bound with it (the same
    # twelve heartbeats). The manager's liveness cost stays bounded; detection takes longer.
    status_period: float = 0.25
    status_rate: float = 1000.0
    default_timeout: float = 5.0
    # An atomic vote holds every later command, so it lasts at most this long whatever the
    # command's timeout (a node that never votes must not stall the system for an hour).
    max_vote_time: float = 60.0
    # How long a (re)started manager listens to participants before deciding its first state;
    # prolonged while participants keep appearing (discovery is slower on a loaded machine),
    # by `recovery_quiet` after the last newcomer, up to three windows in all.
    recovery_window: float = 1.0
    recovery_quiet: float = 0.3
    manager_id: str = ""
    keep_dropped: int = 32
    # The manager's own heartbeat (best effort: the current state again), and the repeats
    # of a new state shortly after it was published, for a lossy link.
    heartbeat_period: float = 0.25
    repeats: tuple[float, ...] = (0.05, 0.15)
    # After recovery, a command naming a layer nobody implements yet waits this long for
    # participants still being discovered before it is refused.
    unknown_layer_grace: float = 2.0
    # Once the manager knows an epoch, a report more than this far above it is a lie (or a
    # stale state file): ignored and logged, never adopted nor persisted.
    max_epoch_jump: int = 10_000
    # At most one log line per sender this often about its rejected statuses.
    rejection_log_period: float = 10.0
    # A manager without a state file numbers its first state this far above the newest
    # epoch it heard: its predecessor may have published states that no participant
    # reported during recovery, and an epoch must never name two configurations.
    memoryless_epoch_gap: int = 1000
    # Commands waiting in the manager at once (synchronous ones for their acknowledgements,
    # others during recovery, an atomic vote or the unknown-layer grace): beyond it a new
    # command is refused at once, naming the limit. Anyone in the domain can send commands.
    max_waiting_commands: int = 1000
    # The layers and relations the manager's own layer files declare (`--layers`): merged
    # with the participants' declarations (`with_layer_files`), so the manager and `rules
    # replay` compose and validate from the same relations. A layer only these declare is
    # known all the same: declared by the manager itself, implemented by no participant.
    layer_files: tuple[LayerDeclaration, ...] = ()
    # The layers whose effect the manager applies itself before it publishes (their
    # bindings: ROS parameters and lifecycle states). A synchronous command naming one of
    # these, or a layer implying one, needs no participant's acknowledgement: with none
    # live, it is answered as applied by 0 nodes (not "it reached no node").
    applied_by_manager: frozenset[str] = frozenset()
