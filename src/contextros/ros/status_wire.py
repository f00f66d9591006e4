"""A participant's status written and read as its serialized bytes (the hot path of both).

The manager takes every status raw and reads it here: rclpy's own take builds a Python
`ParticipantStatus` (each field through a checking property) that `report_from_msg` then
copies, about 50 µs a status against 12-20 µs here; a status whose declarations are the
bytes of the node's previous one reuses their decoded form. A participant publishes its
statuses as bytes written here the same way, its node, incarnation and declarations
encoded once. The layout is the CDR of `ParticipantStatus.msg` (XCDR version 1, little
endian, as Fast DDS, Cyclone DDS and Zenoh write it on the machines ROS 2 runs on); anything
else (big endian, another encapsulation) goes through rclpy's deserialization.

The bytes come from the network: every length is checked against what is left, and a
damaged status raises `ValueError` naming the field (or, through rclpy, saying it is not
readable), never anything else. Whatever rclpy reads, this reads alike (invalid UTF-8
replaced, a string up to its first NUL, a string without its terminator), except that it
refuses some damaged statuses rclpy reads in part (a nested sequence running past the end,
which rclpy reads as empty) and reads a bool byte other than 0 and 1 as true (rclpy
refuses it). What it keeps of the declarations it saw is bounded (`_CACHE_*`).

A participant takes the manager's states raw too (`StateDecoder`): every participant of a
process gets the same bytes, and the heartbeat repeats them, so the last few are decoded
once for the process (rclpy's take builds a `LayerState` message field by field, which
`state_from_msg` then copies: 6 µs against 0.3 µs for bytes seen before).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

from contextros.protocol.events import ParticipantReport
from contextros.protocol.relations import LayerDeclaration
from contextros.protocol.state import LayerState
from contextros.protocol.validation import MAX_LAYERS

# The encapsulation read here (the first two bytes): plain CDR, little endian.
_CDR_LE = b"\x00\x01"
_HEADER = 4
_U32, _U64 = struct.Struct("<I").unpack_from, struct.Struct("<Q").unpack_from
_PACK_U32, _PACK_U64 = struct.Struct("<I").pack, struct.Struct("<Q").pack
_PACK_TIME = struct.Struct("<iI").pack
_TIME = struct.Struct("<iI").unpack_from
_F32 = struct.Struct("<f").unpack_from
# What is kept of nodes' last declarations (participants repeat theirs in every status),
# before any check: bounded whatever a sender makes up. All is forgotten when one is full.
_CACHE_NODES = 4096
_CACHE_DECLARATIONS = 16_384
_CACHE_BYTES = 4 << 20
# A LayerInfo as read: name, excludes, required, group, after, implies.
_Entry = tuple[str, tuple[str, ...], tuple[str, ...], str, tuple[str, ...], tuple[str, ...]]


class StatusDecoder:
    """`decode(data)` gives the `ParticipantReport` of a serialized `ParticipantStatus`."""

    def __init__(self) -> None:
        # Each node's last declarations: their bytes, and what they decoded to.
        self._last_layers: dict[str, tuple[bytes, tuple[LayerDeclaration, ...]]] = {}
        self._cached_declarations = self._cached_bytes = 0

    def decode(self, data: bytes) -> ParticipantReport:
        if data[:2] != _CDR_LE:
            return _decoded_by_rclpy(data)
        u32, u64 = _U32, _U64
        size = len(data)
        pos = _HEADER
        field = ""

        # Each reader moves `pos` on; positions are relative to the payload, as CDR aligns.
        def count() -> int:
            nonlocal pos
            pos += -(pos - _HEADER) & 3
            if pos + 4 > size:
                raise ValueError(f"status field {field} runs past the message's end")
            pos += 4
            value: int = u32(data, pos - 4)[0]
            return value

        def string() -> str:
            nonlocal pos
            length = count()
            start = pos
            pos += length
            if pos > size:
                raise ValueError(f"status field {field} runs past the message's end")
            text = data[start:pos]  # with its terminating NUL, if the writer sent one
            cut = text.find(0)  # rclpy reads a C string: up to the first NUL
            return (text if cut < 0 else text[:cut]).decode(errors="replace")

        def strings() -> tuple[str, ...]:
            entries = count()
            if entries * 4 > size - pos:  # each string takes 4 bytes at least
                raise ValueError(f"status field {field} claims {entries} entries")
            return tuple([string() for _ in range(entries)])

        def uint64() -> int:
            nonlocal pos
            pos += -(pos - _HEADER) & 7
            if pos + 8 > size:
                raise ValueError(f"status field {field} runs past the message's end")
            pos += 8
            value: int = u64(data, pos - 8)[0]
            return value

        def boolean() -> bool:
            nonlocal pos
            if pos >= size:
                raise ValueError(f"status field {field} runs past the message's end")
            pos += 1
            return data[pos - 1] != 0

        field = "node"
        node = string()
        field = "incarnation"
        incarnation = string()
        field = "layers"
        pos += -(pos - _HEADER) & 3
        start = pos
        last = self._last_layers.get(node)
        if last is not None and data.startswith(last[0], start):
            # The same bytes as this node's previous status: the same declarations.
            layers = last[1]
            pos += len(last[0])
        else:
            entries = count()
            if entries * 24 > size - pos:  # each LayerInfo takes 24 bytes at least
                raise ValueError(f"status field layers claims {entries} entries")
            decoded = [
                (string(), strings(), strings(), string(), strings(), strings())
                for _ in range(entries)
            ]
            layers = self._remember(node, data[start:pos], decoded)
        field = "applied_epoch"
        applied_epoch = uint64()
        field = "applied_manager_id"
        applied_manager_id = string()
        field = "active_layers"
        active = strings()
        field = "in_critical_section"
        in_critical_section = boolean()
        field = "pending_epoch"
        pending_epoch = uint64()
        field = "failed_epoch"
        failed_epoch = uint64()
        field = "error"
        error = string()
        field = "leaving"
        leaving = boolean()
        field = "stamp"
        count()  # sec, then nanosec
        count()
        field = "hosted_nodes"
        hosted = strings()
        field = "manager_lost"
        manager_lost = boolean()
        field = "vote_epoch"
        vote_epoch = uint64()
        field = "vote_manager_id"
        vote_manager_id = string()
        field = "vote_yes"
        vote_yes = boolean()
        field = "vote_reason"
        vote_reason = string()
        field = "language"
        string()
        return ParticipantReport(
            node=node,
            incarnation=incarnation,
            layers=layers,
            applied_epoch=applied_epoch,
            applied_manager_id=applied_manager_id,
            active=active,
            in_critical_section=in_critical_section,
            pending_epoch=pending_epoch,
            failed_epoch=failed_epoch,
            error=error,
            leaving=leaving,
            hosted=hosted,
            manager_lost=manager_lost,
            vote_epoch=vote_epoch,
            vote_manager_id=vote_manager_id,
            vote_yes=vote_yes,
            vote_reason=vote_reason,
        )

    def _remember(
        self, node: str, key: bytes, decoded: list[_Entry]
    ) -> tuple[LayerDeclaration, ...]:
        layers = tuple(
            LayerDeclaration(
                name=name,
                excludes=frozenset(excludes),
                requires=frozenset(required),
                group=group,
                after=frozenset(after),
                implies=frozenset(implies),
            )
            for name, excludes, required, group, after, implies in decoded
        )
        if len(layers) > MAX_LAYERS:  # refused by the checks anyway: not worth keeping
            return layers
        full = (
            len(self._last_layers) >= _CACHE_NODES
            or self._cached_declarations + len(layers) > _CACHE_DECLARATIONS
            or self._cached_bytes + len(key) > _CACHE_BYTES
        )
        if full:  # statuses under many names, or huge ones
            self._last_layers.clear()
            self._cached_declarations = self._cached_bytes = 0
        previous = self._last_layers.pop(node, None)
        if previous is not None:
            self._cached_declarations -= len(previous[1])
            self._cached_bytes -= len(previous[0])
        self._last_layers[node] = (key, layers)
        self._cached_declarations += len(layers)
        self._cached_bytes += len(key)
        return layers


def _decoded_by_rclpy(data: bytes) -> ParticipantReport:
    """Another encoding: read by rclpy (the message type's own code), then converted."""
    from contextros_interfaces.msg import ParticipantStatus
    from rclpy.serialization import deserialize_message

    from contextros.ros.messages import report_from_msg

    try:
        message = deserialize_message(data, ParticipantStatus)
    except RuntimeError as error:  # rclpy's RMWError
        raise ValueError(f"status not readable: {error}") from None
    return report_from_msg(message)


# States a participant keeps decoded (by their bytes), and the largest one it keeps.
_STATES_KEPT = 8
_STATE_BYTES_KEPT = 4096


class StateDecoder:
    """`decode(data)` gives the `LayerState` of a serialized `LayerState` message; the last
    few are kept by their bytes (the states are immutable: one object serves every
    participant of the process). Safe to share between threads: a lookup or a store is
    one dictionary operation, and a full memory is replaced, not emptied."""

    def __init__(self) -> None:
        self._known: dict[bytes, LayerState] = {}

    def decode(self, data: bytes) -> LayerState:
        known = self._known
        state = known.get(data)
        if state is None:
            state = _state_from_bytes(data)
            if len(data) <= _STATE_BYTES_KEPT:
                if len(known) >= _STATES_KEPT:
                    known = self._known = {}
                known[data] = state
        return state


def _state_from_bytes(data: bytes) -> LayerState:
    """The state in `data` (checked as a status is: `ValueError` naming the field)."""
    if data[:2] != _CDR_LE:
        from contextros_interfaces.msg import LayerState as LayerStateMsg
        from rclpy.serialization import deserialize_message

        from contextros.ros.messages import state_from_msg

        try:
            return state_from_msg(deserialize_message(data, LayerStateMsg))
        except RuntimeError as error:  # rclpy's RMWError
            raise ValueError(f"state not readable: {error}") from None
    reader = _Reader(data)
    epoch = reader.uint64("epoch")
    entries = reader.uint32("active_layers")
    if entries * 4 > len(data) - reader.pos:  # each string takes 4 bytes at least
        raise ValueError(f"state field active_layers claims {entries} entries")
    active = tuple([reader.string("active_layers") for _ in range(entries)])
    sec, nanosec = _TIME(data, reader.take("stamp", 8, align=4))
    requester, reason = reader.string("requester"), reader.string("reason")
    manager_id = reader.string("manager_id")
    return LayerState(
        epoch=epoch,
        active=active,
        stamp=float(sec) + float(nanosec) * 1e-9,  # as messages.stamp_to_seconds
        requester=requester,
        reason=reason,
        manager_id=manager_id,
        status_period=_F32(data, reader.take("status_period", 4))[0],
    )


class _Reader:
    """Reads CDR fields in order from `data`, each length checked against what is left."""

    def __init__(self, data: bytes) -> None:
        self.data, self.size, self.pos = data, len(data), _HEADER

    def take(self, field: str, size: int, align: int = 0) -> int:
        """The position of a field of `size` bytes (aligned to its size, or to `align`),
        moving past it."""
        self.pos += -(self.pos - _HEADER) & ((align or size) - 1)
        start = self.pos
        self.pos += size
        if self.pos > self.size:
            raise ValueError(f"state field {field} runs past the message's end")
        return start

    def uint32(self, field: str) -> int:
        value: int = _U32(self.data, self.take(field, 4))[0]
        return value

    def uint64(self, field: str) -> int:
        value: int = _U64(self.data, self.take(field, 8))[0]
        return value

    def string(self, field: str) -> str:
        length = self.uint32(field)
        start = self.pos
        self.pos += length
        if self.pos > self.size:
            raise ValueError(f"state field {field} runs past the message's end")
        text = self.data[start : self.pos]  # with its terminating NUL, if the writer sent one
        cut = text.find(0)  # rclpy reads a C string: up to the first NUL
        return (text if cut < 0 else text[:cut]).decode(errors="replace")


class StatusEncoder:
    """`encode(report, wall_time)`: the CDR bytes of `report_to_msg(report, wall_time)`, as
    rclpy would serialize them (with language "Python")."""

    def __init__(self) -> None:
        self._prefix_of: tuple[str, str, tuple[LayerDeclaration, ...]] | None = None
        self._prefix = b""

    def encode(self, report: ParticipantReport, wall_time: float) -> bytes:
        key = (report.node, report.incarnation, report.layers)
        if key != self._prefix_of:
            self._prefix, self._prefix_of = _encoded_prefix(report), key
        out = bytearray(self._prefix)
        _align(out, 8)
        out += _PACK_U64(report.applied_epoch)
        _string(out, report.applied_manager_id)
        _strings(out, report.active)
        out.append(report.in_critical_section)
        _align(out, 8)
        out += _PACK_U64(report.pending_epoch)
        out += _PACK_U64(report.failed_epoch)
        _string(out, report.error)
        out.append(report.leaving)
        _align(out, 4)
        sec = int(wall_time)  # as messages.seconds_to_stamp
        out += _PACK_TIME(sec, int((wall_time - sec) * 1e9))
        _strings(out, report.hosted)
        out.append(report.manager_lost)
        _align(out, 8)
        out += _PACK_U64(report.vote_epoch)
        _string(out, report.vote_manager_id)
        out.append(report.vote_yes)
        _string(out, report.vote_reason)
        _string(out, "Python")
        return bytes(out)


def _encoded_prefix(report: ParticipantReport) -> bytes:
    """The header, node, incarnation and declarations: what a participant repeats."""
    out = bytearray(_CDR_LE + b"\x00\x00")
    _string(out, report.node)
    _string(out, report.incarnation)
    _align(out, 4)
    out += _PACK_U32(len(report.layers))
    for declaration in report.layers:
        _string(out, declaration.name)
        _strings(out, sorted(declaration.excludes))
        _strings(out, sorted(declaration.requires))
        _string(out, declaration.group)
        _strings(out, sorted(declaration.after))
        _strings(out, sorted(declaration.implies))
    return bytes(out)


def _align(out: bytearray, size: int) -> None:
    out += bytes(-(len(out) - _HEADER) % size)


def _string(out: bytearray, text: str) -> None:
    data = text.encode()
    _align(out, 4)
    out += _PACK_U32(len(data) + 1)
    out += data
    out.append(0)


def _strings(out: bytearray, texts: Iterable[str]) -> None:
    listed = list(texts)
    _align(out, 4)
    out += _PACK_U32(len(listed))
    for text in listed:
        _string(out, text)
