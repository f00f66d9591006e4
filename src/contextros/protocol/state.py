"""The manager's layer state: a numbered full snapshot of the active layers.

States are never deltas: a participant that missed or reordered some of them still ends
on the right configuration by applying the newest one, and refuses anything older.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from contextros.protocol.errors import StateFileError

# Epochs go up by one per state. At a thousand states a second, 2**48 is reached after
# 8,900 years: an epoch above it was not produced by an honest manager, and refusing it
# keeps every `epoch + 1` far from the uint64 limit (2**64 - 1 crashed the old manager).
MAX_EPOCH = 2**48


@dataclass(frozen=True)
class LayerState:
    """One configuration of the whole system, as the manager decided it.

    `active` is in activation order: the last layer is the outermost one (its partials run
    first), exactly what the core's `set_active` expects.
    """

    epoch: int
    active: tuple[str, ...] = ()
    requester: str = ""
    reason: str = ""
    # When it was decided, on the clock of whoever produced this value (protocol time in
    # the manager, wall-clock time once it crossed the wire or a file); not part of identity.
    stamp: float = field(default=0.0, compare=False)
    manager_id: str = field(default="", compare=False)

    def to_json(self, wall_time: float | None = None) -> str:
        return json.dumps(
            {
                "epoch": self.epoch,
                "active": list(self.active),
                "requester": self.requester,
                "reason": self.reason,
                "stamp": self.stamp if wall_time is None else wall_time,
            },
            indent=2,
        )

    @classmethod
    def from_json(cls, text: str, source: str = "<state>") -> LayerState:
        """Parse a saved state; a damaged file is an error, never a silent epoch 0."""
        try:
            data = json.loads(text)
            epoch = data["epoch"]
            active = data["active"]
            if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
                raise ValueError(f"epoch must be a non-negative integer, got {epoch!r}")
            if epoch > MAX_EPOCH:
                raise ValueError(f"epoch {epoch} is beyond any epoch an honest manager issues")
            if not isinstance(active, list) or not all(
                isinstance(n, str) and n.isidentifier() for n in active
            ):
                raise ValueError("active must be a list of layer names")
            return cls(
                epoch=epoch,
                active=tuple(active),
                requester=str(data.get("requester", "")),
                reason=str(data.get("reason", "")),
                stamp=float(data.get("stamp", 0.0)),
            )
        except (ValueError, KeyError, TypeError) as error:
            raise StateFileError(
                f"{source}: not a ContextROS state file ({error}); "
                "fix or delete it to start from the participants' state"
            ) from error


INITIAL_STATE = LayerState(epoch=0, active=(), requester="", reason="initial")


@dataclass(frozen=True)
class KnownParticipant:
    """A participant the manager knew live: after a restart it is awaited, not forgotten."""

    node: str
    incarnation: str
    hosted: tuple[str, ...] = ()


@dataclass(frozen=True)
class ManagerMemory:
    """What a manager with a state file keeps across a crash: its last published state,
    the highest epoch it ever proposed (an atomic vote's epoch is never reused, even when
    the crash came before the commit) and the participants it knew live. The adapter
    writes it before anything that changes it goes on the wire (docs/protocol.md)."""

    state: LayerState
    proposed_epoch: int = 0
    participants: tuple[KnownParticipant, ...] = ()

    def to_json(self, wall_time: float | None = None) -> str:
        data = json.loads(self.state.to_json(wall_time))
        data["proposed_epoch"] = self.proposed_epoch
        data["participants"] = [
            {"node": p.node, "incarnation": p.incarnation, "hosted": list(p.hosted)}
            for p in self.participants
        ]
        return json.dumps(data, indent=2)

    @classmethod
    def from_json(cls, text: str, source: str = "<state>") -> ManagerMemory:
        """Parse a state file (one written before `proposed_epoch` and `participants`
        existed reads as none of either); a damaged file is an error."""
        state = LayerState.from_json(text, source)
        try:
            data = json.loads(text)
            proposed = data.get("proposed_epoch", 0)
            if not isinstance(proposed, int) or isinstance(proposed, bool):
                raise ValueError(f"proposed_epoch must be an integer, got {proposed!r}")
            if not 0 <= proposed <= MAX_EPOCH:
                raise ValueError(f"proposed_epoch {proposed} is out of range")
            participants = []
            for entry in data.get("participants", []):
                node, incarnation = entry["node"], entry["incarnation"]
                hosted = entry.get("hosted", [])
                if not (isinstance(node, str) and node.startswith("/")):
                    raise ValueError(f"participant node must be a node name, got {node!r}")
                if not isinstance(incarnation, str) or not isinstance(hosted, list):
                    raise ValueError(f"participant {node}: bad incarnation or hosted nodes")
                if not all(isinstance(h, str) for h in hosted):
                    raise ValueError(f"participant {node}: hosted nodes must be names")
                participants.append(KnownParticipant(node, incarnation, tuple(hosted)))
        except (ValueError, KeyError, TypeError) as error:
            raise StateFileError(
                f"{source}: not a ContextROS state file ({error}); "
                "fix or delete it to start from the participants' state"
            ) from error
        return cls(state, proposed, tuple(participants))
