"""Repairing a recording whose writer was killed: every whole record up to where the file
stops being readable copied into a new, complete MCAP file (summary, indexes, footer), as
`ros2 bag reindex` restores a bag's metadata and the mcap CLI's `recover` does. The copy
stops at the first damaged record: what follows it (whole chunks too) is not copied.

Messages are copied as stored (their encoded bytes), whatever their encoding, so nothing
needs decoding; schemas and channels are renumbered in the order they come. The new file
is written beside the target and put into place once whole: an interrupted repair leaves
no half file, and an existing target is replaced only when asked to.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from contextros.recording.reader import Damage, RecordingError, mcap_records, open_recording
from contextros.recording.writer import compression


@dataclass
class Repair:
    """What a repair copied, and where the input stopped being readable (None: nowhere;
    its `messages`: those copied before it, all of them)."""

    messages: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    start: float | None = None  # the first and last log times, seconds since the epoch
    end: float | None = None
    damage: Damage | None = None
    complete: bool = False  # the input had its summary: it needed no repair


def repair_recording(
    source: str | os.PathLike[str], target: str | os.PathLike[str], *, replace: bool = False
) -> Repair:
    """Copy every whole record of `source`, up to the first damaged one, into a complete
    MCAP file at `target` (an existing one only if `replace`). RecordingError when `source`
    cannot be read at all (not MCAP, cannot be opened) or `target` exists or cannot be
    written."""
    from mcap.records import (
        Attachment,
        Channel,
        Footer,
        Header,
        Message,
        Metadata,
        Schema,
    )
    from mcap.writer import Writer

    name, output = os.fspath(source), Path(target)
    if output.exists() and output.resolve() == Path(name).resolve():
        raise RecordingError(f"{name}: the repaired copy must go to another file")
    if output.exists() and not replace:
        raise RecordingError(f"{output} exists already: not replaced (--force replaces it)")
    partial = output.with_name(f".{output.name}.partial")
    report = Repair()
    schemas: dict[int, int] = {}  # the input's schema id -> the output's
    channels: dict[int, int] = {}
    topics: dict[int, str] = {}
    try:
        with open_recording(name) as stream, partial.open("wb") as out:
            writer: Any = None
            records = mcap_records(stream, name)
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    break
                except RecordingError as error:
                    if error.damage is None or error.damage.offset == 0:
                        raise  # not MCAP at all: nothing to copy
                    report.damage = dataclasses.replace(error.damage, messages=report.messages)
                    break
                if writer is None:
                    profile = record.profile if isinstance(record, Header) else ""
                    library = record.library if isinstance(record, Header) else ""
                    writer = Writer(out, compression=compression())
                    writer.start(profile=profile, library=library or "contextros repair")
                if isinstance(record, Schema) and record.id not in schemas:
                    schemas[record.id] = writer.register_schema(
                        record.name, record.encoding, record.data
                    )
                elif isinstance(record, Channel) and record.id not in channels:
                    channels[record.id] = writer.register_channel(
                        record.topic,
                        record.message_encoding,
                        schemas.get(record.schema_id, 0),
                        record.metadata,
                    )
                    topics[record.id] = record.topic
                elif isinstance(record, Message) and record.channel_id in channels:
                    writer.add_message(
                        channels[record.channel_id],
                        record.log_time,
                        record.data,
                        record.publish_time,
                        record.sequence,
                    )
                    _count(report, topics[record.channel_id], record.log_time / 1e9)
                elif isinstance(record, Attachment):
                    writer.add_attachment(
                        record.create_time,
                        record.log_time,
                        record.name,
                        record.media_type,
                        record.data,
                    )
                elif isinstance(record, Metadata):
                    writer.add_metadata(record.name, record.metadata)
                elif isinstance(record, Footer):
                    report.complete = True
            if writer is None:  # an empty file, or cut inside its first record
                writer = Writer(out, compression=compression())
                writer.start(profile="", library="contextros repair")
            writer.finish()
        if replace:
            os.replace(partial, output)
        else:
            os.link(partial, output)  # fails if one appeared meanwhile: never replaced
    except OSError as error:
        raise RecordingError(f"{output}: cannot write the repaired copy: {error}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            partial.unlink()
    return report


def _count(report: Repair, topic: str, time: float) -> None:
    report.messages += 1
    report.topics[topic] = report.topics.get(topic, 0) + 1
    report.start = time if report.start is None else min(report.start, time)
    report.end = time if report.end is None else max(report.end, time)
