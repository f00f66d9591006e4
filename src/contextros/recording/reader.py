"""Reading a ROS 2 MCAP file, record by record, decoded without ROS.

The file is read sequentially (it need not have a summary section), so a damaged one still
gives the messages before the damage, and the error says at which byte it broke. Messages
that cannot be decoded here (a schema that is not `ros2msg` with CDR, such as an IDL or
JSON one) are skipped, with one note per type.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from typing import Any, BinaryIO

from contextros.errors import LayerError


class RecordingError(LayerError):
    """A recording that cannot be read: the message names the file and where it broke."""


@dataclass(frozen=True)
class RecordedMessage:
    time: float  # the log time, seconds since the epoch (when the recorder received it)
    topic: str
    type_name: str  # the schema's name: 'sensor_msgs/msg/BatteryState'
    message: Any  # decoded: fields as attributes, as on a message object


def read_recording(
    path: str | os.PathLike[str],
    topics: Collection[str] | None = None,
    note: Callable[[str], object] = lambda text: None,
) -> Iterator[RecordedMessage]:
    """The messages of `path` (of `topics` only, if given) in file order. RecordingError
    when the file is not MCAP, is damaged or ends early; `note` hears of skipped types."""
    try:
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import StreamReader
        from mcap_ros2.decoder import DecoderFactory
    except ImportError as error:
        raise RecordingError(
            f"reading recordings needs the mcap packages ({error}): "
            "pip install 'contextros[observe]'"
        ) from None
    name = os.fspath(path)
    try:
        stream: BinaryIO = open(name, "rb")  # noqa: SIM115 - closed below, after the loop
    except OSError as error:
        raise RecordingError(f"{name}: cannot open the recording: {error.strerror}") from None
    factory = DecoderFactory()
    schemas: dict[int, Any] = {}
    channels: dict[int, Any] = {}
    decoders: dict[int, Callable[[bytes], Any] | None] = {}
    skipped: set[str] = set()
    count = 0
    with stream:
        reader = StreamReader(stream, validate_crcs=True, record_size_limit=1 << 30)
        records = reader.records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception as error:  # whatever a damaged file makes the library raise
                raise RecordingError(_broken(name, stream, count, error)) from None
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


def _broken(name: str, stream: BinaryIO, count: int, error: Exception) -> str:
    where = f"byte {stream.tell()}"
    kind = type(error).__name__
    at_end = stream.tell() >= os.fstat(stream.fileno()).st_size
    if kind in ("EndOfFile", "EOFError") or (at_end and kind != "InvalidMagic"):
        what = "the file ends in the middle of a record (truncated: was the recorder killed?)"
    elif kind == "InvalidMagic":
        what = "not an MCAP file (no MCAP magic bytes)"
    else:
        what = f"{kind}: {error}"
    return f"{name}: {where}: {what}; {count} messages were read before it"
