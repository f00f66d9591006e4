"""Reading a ROS 2 MCAP file, record by record, decoded without ROS.

The file is read sequentially (it need not have a summary section), so a damaged one still
gives the records before the damage, and the error says at which byte it broke. A file
that merely ends early (its recorder was killed: the last chunk cut short, or no summary)
is *truncated*: a reader that accepts it (`truncated=`) gets every message before the cut.
Messages that cannot be decoded here (a schema that is not `ros2msg` with CDR, such as an
IDL or JSON one) are skipped, with one note per type.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from typing import Any, BinaryIO

from contextros.errors import LayerError

MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = 9  # opcode (1 byte) and length (8 bytes)


@dataclass(frozen=True)
class Damage:
    """Where a recording stops being readable, and why."""

    path: str
    offset: int  # the byte where the unreadable part begins
    what: str
    truncated: bool  # it only ends early (a recorder killed), nothing in it is wrong
    messages: int = 0  # messages read before it

    def __str__(self) -> str:
        return f"{self.path}: byte {self.offset}: {self.what}"


class RecordingError(LayerError):
    """A recording that cannot be read: the message names the file and where it broke."""

    def __init__(self, message: str, damage: Damage | None = None) -> None:
        super().__init__(message)
        self.damage = damage


@dataclass(frozen=True)
class RecordedMessage:
    time: float  # the log time, seconds since the epoch (when the recorder received it)
    topic: str
    type_name: str  # the schema's name: 'sensor_msgs/msg/BatteryState'
    message: Any  # decoded: fields as attributes, as on a message object


def open_recording(path: str | os.PathLike[str]) -> BinaryIO:
    name = os.fspath(path)
    try:
        return open(name, "rb")  # the caller closes it
    except OSError as error:
        raise RecordingError(f"{name}: cannot open the recording: {error.strerror}") from None


def mcap_records(stream: BinaryIO, name: str) -> Iterator[Any]:
    """Every record of an MCAP stream in file order, a chunk's records in place of the
    chunk; RecordingError (with its `damage`) where the file stops being readable."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    reader = StreamReader(stream, emit_chunks=True, validate_crcs=True, record_size_limit=1 << 30)
    records = reader.records
    size = os.fstat(stream.fileno()).st_size
    good = len(MAGIC)  # the end of the last whole record: where any damage begins
    while True:
        try:
            record = next(records)
            if stream.tell() >= size and _cut_short(stream, good):
                raise EOFError("the last record is cut short")  # the library reads short
            inside = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else ()
        except StopIteration:
            return
        except Exception as error:  # whatever a damaged file makes the library raise
            damage = _damage(name, stream, good, error)
            raise RecordingError(str(damage), damage) from None
        good = stream.tell()
        if isinstance(record, Chunk):
            yield from inside
        else:
            yield record


def read_recording(
    path: str | os.PathLike[str],
    topics: Collection[str] | None = None,
    note: Callable[[str], object] = lambda text: None,
    truncated: Callable[[Damage], object] | None = None,
) -> Iterator[RecordedMessage]:
    """The messages of `path` (of `topics` only, if given) in file order. RecordingError
    when the file is not MCAP, is damaged or ends early; with `truncated`, a file that only
    ends early gives its messages and then `truncated` hears where it ended. `note` hears
    of skipped types."""
    try:
        from mcap.records import Channel, Message, Schema
        from mcap_ros2.decoder import DecoderFactory
    except ImportError as error:
        raise RecordingError(
            f"reading recordings needs the mcap packages ({error}): "
            "pip install 'contextros[observe]'"
        ) from None
    name = os.fspath(path)
    factory = DecoderFactory()
    schemas: dict[int, Any] = {}
    channels: dict[int, Any] = {}
    decoders: dict[int, Callable[[bytes], Any] | None] = {}
    skipped: set[str] = set()
    count = 0
    with open_recording(name) as stream:
        records = mcap_records(stream, name)
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except RecordingError as error:
                damage = error.damage
                assert damage is not None
                damage = Damage(damage.path, damage.offset, damage.what, damage.truncated, count)
                if truncated is not None and damage.truncated:
                    truncated(damage)
                    return
                raise RecordingError(
                    f"{damage}; {count} messages were read before it", damage
                ) from None
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:
                    raise RecordingError(
                        f"{name}: byte {stream.tell()}: a message on channel "
                        f"{record.channel_id}, which no channel record declared"
                    )
                if topics is not None and channel.topic not in topics:
                    continue
                schema = schemas.get(channel.schema_id)
                type_name = schema.name if schema is not None else "(no schema)"
                if channel.id not in decoders:
                    decoders[channel.id] = _decoder(factory, channel, schema)
                decode = decoders[channel.id]
                if decode is None:
                    if type_name not in skipped:
                        skipped.add(type_name)
                        encoding = channel.message_encoding or "no"
                        note(
                            f"{name}: messages of type {type_name} ({encoding} encoding, on "
                            f"{channel.topic}) skipped: not a ROS 2 message this reader decodes"
                        )
                    continue
                try:
                    message = decode(record.data)
                except Exception as error:  # the data do not match their own schema
                    raise RecordingError(
                        f"{name}: byte {stream.tell()}: message {count + 1} on {channel.topic} "
                        f"does not decode as {type_name}: {error}"
                    ) from None
                count += 1
                yield RecordedMessage(record.log_time / 1e9, channel.topic, type_name, message)


def _decoder(factory: Any, channel: Any, schema: Any) -> Callable[[bytes], Any] | None:
    try:
        decoder: Callable[[bytes], Any] | None = factory.decoder_for(
            channel.message_encoding, schema
        )
    except Exception:  # a schema text its parser refuses: treated as an unknown type
        return None
    return decoder


def _cut_short(stream: BinaryIO, start: int) -> bool:
    """Whether the record at `start` claims more bytes than the file has."""
    here = stream.tell()
    stream.seek(start)
    header = stream.read(_RECORD_HEADER)
    stream.seek(here)
    length = int.from_bytes(header[1:], "little")
    return len(header) < _RECORD_HEADER or start + _RECORD_HEADER + length > here


def _damage(name: str, stream: BinaryIO, good: int, error: Exception) -> Damage:
    """What is wrong at `good` (the end of the last whole record): read again from there."""
    size = os.fstat(stream.fileno()).st_size
    stream.seek(0)
    start = stream.read(len(MAGIC))
    if start != MAGIC[: len(start)]:
        return Damage(name, 0, "not an MCAP file (no MCAP magic bytes)", truncated=False)
    if size <= len(MAGIC):
        what = "the file is empty" if size == 0 else "the file ends in its magic bytes"
        return Damage(name, size, f"{what} (truncated: was the recorder killed?)", True)
    stream.seek(good)
    header = stream.read(_RECORD_HEADER)
    end = good + _RECORD_HEADER + int.from_bytes(header[1:], "little")
    if good >= size:
        what = "the file ends after its last whole record, without its summary"
    elif len(header) < _RECORD_HEADER or end > size:
        what = "the file ends in the middle of a record"
    else:
        kind = type(error).__name__
        return Damage(name, good, f"damaged record ({kind}: {error})", truncated=False)
    return Damage(name, good, f"{what} (truncated: was the recorder killed?)", truncated=True)
