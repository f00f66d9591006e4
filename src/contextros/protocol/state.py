"""The manager's layer state: a numbered full snapshot of the active layers.

States are never deltas: a participant that missed or reordered some of them still ends
on the right configuration by applying the newest one, and refuses anything older.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
    # Sent with it, not part of it: the heartbeat period (seconds) the manager asks of its
    # participants while nothing changes; 0: their own (0.25 s by default).
    status_period: float = field(default=0.0, compare=False)

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
        return cls._from_fields(_json_object(text, source), source)

    @classmethod
    def _from_fields(cls, data: dict[str, Any], source: str) -> LayerState:
        epoch = _field(data, "epoch", source)
        active = _field(data, "active", source)
        if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
            raise _damaged(
                source, f"field 'epoch' must be a non-negative integer, not {_shown(epoch)}"
            )
        if epoch > MAX_EPOCH:
            raise _damaged(source, f"epoch {epoch} is beyond any epoch an honest manager issues")
        if not isinstance(active, list) or not all(
            isinstance(n, str) and n.isidentifier() for n in active
        ):
            raise _damaged(
                source, f"field 'active' must be a list of layer names, not {_shown(active)}"
            )
        texts = {name: data.get(name, "") for name in ("requester", "reason")}
        for name, value in texts.items():
            if not isinstance(value, str):
                raise _damaged(source, f"field {name!r} must be a string, not {_shown(value)}")
        stamp = data.get("stamp", 0.0)
        if (
            not isinstance(stamp, int | float)
            or isinstance(stamp, bool)
            or not math.isfinite(stamp)
        ):
            raise _damaged(source, f"field 'stamp' must be a number, not {_shown(stamp)}")
        return cls(epoch=epoch, active=tuple(active), stamp=float(stamp), **texts)


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
    the crash came before the commit), the participants it knew live, and which active
    layers were asked for explicitly (the others are active because implied: deactivating
    what implied them takes them out). The adapter writes it before anything that changes
    it goes on the wire (docs/protocol.md)."""

    state: LayerState
    proposed_epoch: int = 0
    participants: tuple[KnownParticipant, ...] = ()
    # None: not recorded (a file written before `implies`): every active layer was asked.
    explicit: tuple[str, ...] | None = None

    def to_json(self, wall_time: float | None = None) -> str:
        data = json.loads(self.state.to_json(wall_time))
        data["proposed_epoch"] = self.proposed_epoch
        data["participants"] = [
            {"node": p.node, "incarnation": p.incarnation, "hosted": list(p.hosted)}
            for p in self.participants
        ]
        if self.explicit is not None:
            data["explicit"] = list(self.explicit)
        return json.dumps(data, indent=2)

    @classmethod
    def from_json(cls, text: str, source: str = "<state>") -> ManagerMemory:
        """Parse a state file (one written before `proposed_epoch`, `participants` and
        `explicit` existed reads as none of them); a damaged file is an error naming what
        is wrong."""
        data = _json_object(text, source)
        state = LayerState._from_fields(data, source)
        proposed = data.get("proposed_epoch", 0)
        if not isinstance(proposed, int) or isinstance(proposed, bool):
            raise _damaged(
                source, f"field 'proposed_epoch' must be an integer, not {_shown(proposed)}"
            )
        if not 0 <= proposed <= MAX_EPOCH:
            raise _damaged(source, f"field 'proposed_epoch' {proposed} is out of range")
        entries = data.get("participants", [])
        if not isinstance(entries, list):
            raise _damaged(source, f"field 'participants' must be a list, not {_shown(entries)}")
        explicit = data.get("explicit")
        if explicit is not None and (
            not isinstance(explicit, list)
            or not all(isinstance(n, str) and n in state.active for n in explicit)
        ):
            raise _damaged(
                source,
                f"field 'explicit' must list active layers, not {_shown(explicit)}",
            )
        participants = tuple(_participant(e, source) for e in entries)
        return cls(state, proposed, participants, None if explicit is None else tuple(explicit))

    @classmethod
    def read(cls, path: Path) -> ManagerMemory | None:
        """The memory in the state file `path`, None if there is none; StateFileError naming
        the file and what is wrong with it if it cannot be read or is damaged."""
        if not path.exists():
            return None
        if path.is_dir():
            raise _damaged(str(path), "it is a directory")
        if not path.is_file():
            raise _damaged(str(path), "it is not a regular file")
        try:
            raw = path.read_bytes()
        except OSError as error:
            raise StateFileError(f"{path}: cannot be read ({error.strerror})") from error
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as error:
            raise _damaged(str(path), f"not UTF-8 at byte {error.start}") from error
        return cls.from_json(text, str(path))


def _damaged(source: str, what: str) -> StateFileError:
    return StateFileError(
        f"{source}: not a ContextROS state file: {what}; "
        "fix or delete it to start from the participants' state"
    )


def _json_object(text: str, source: str) -> dict[str, Any]:
    if not text.strip():
        raise _damaged(source, "it is empty")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        where = f"line {error.lineno} column {error.colno}"
        raise _damaged(source, f"not JSON at {where} ({error.msg.removesuffix(' at')})") from error
    except RecursionError as error:
        raise _damaged(source, "not JSON (nested too deeply)") from error
    except ValueError as error:  # an integer past Python's 4300-digit limit
        digits = len(max(re.findall(r"\d+", text), key=len, default=""))
        raise _damaged(source, f"not JSON (a number of {digits} digits)") from error
    if not isinstance(data, dict):
        raise _damaged(source, f"not a JSON object but {_shown(data)}")
    return data


def _field(data: dict[str, Any], name: str, source: str) -> Any:
    if name not in data:
        raise _damaged(source, f"missing field {name!r}")
    return data[name]


def _participant(entry: Any, source: str) -> KnownParticipant:
    if not isinstance(entry, dict):
        raise _damaged(source, f"a participant must be a JSON object, not {_shown(entry)}")
    node = _field(entry, "node", source)
    incarnation = _field(entry, "incarnation", source)
    hosted = entry.get("hosted", [])
    if not (isinstance(node, str) and node.startswith("/")):
        raise _damaged(source, f"participant node must be a node name, not {_shown(node)}")
    if not isinstance(incarnation, str):
        raise _damaged(source, f"participant {node}: incarnation must be a string")
    if not isinstance(hosted, list) or not all(isinstance(h, str) for h in hosted):
        raise _damaged(source, f"participant {node}: hosted nodes must be a list of names")
    return KnownParticipant(node, incarnation, tuple(hosted))


_JSON_KINDS = {dict: "an object", list: "a list", str: "a string", bool: "true or false"}


def _shown(value: Any) -> str:
    """A JSON value's kind, with the value when it is short: `a list`, `a string ('3')`."""
    if value is None:
        return "null"
    kind = _JSON_KINDS.get(type(value), "a number")
    if isinstance(value, dict | list):
        return kind
    text = repr(value)
    return f"{kind} ({text})" if len(text) <= 40 else kind
