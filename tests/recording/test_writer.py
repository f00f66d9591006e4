"""What a killed recorder leaves: the file as `RecordingWriter` had written it at any
moment, read back up to the cut, and repaired into a file the upstream mcap reader reads."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mcap_ros2")
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from contextros.recording import read_recording
from contextros.recording.definitions import message_definition
from contextros.recording.reader import Damage
from contextros.recording.repair import repair_recording
from contextros.recording.writer import RecordingWriter

FLOAT = "std_msgs/msg/Float64"


def cdr_float(value: float) -> bytes:
    import struct

    return b"\x00\x01\x00\x00" + struct.pack("<d", value)  # CDR little-endian header, float64


def write_until_killed(path: Path, messages: int, per_chunk: int) -> list[int]:
    """A recording in progress, never finished: `close_chunk` after every `per_chunk`
    messages (as the recorder's timer does). The file's size after each chunk is returned."""
    stream = path.open("wb")
    writer = RecordingWriter(stream)
    schema = writer.add_schema(FLOAT, "ros2msg", message_definition(FLOAT).encode())
    channel = writer.add_channel("/level", "cdr", schema)
    sizes = [path.stat().st_size]
    for index in range(messages):
        at = 1_000_000_000 * (100 + index)
        writer.add_message(channel, at, cdr_float(float(index)), at, index + 1)
        if (index + 1) % per_chunk == 0:
            writer.close_chunk()
            sizes.append(path.stat().st_size)
    stream.close()  # as the kernel closes a killed process's file: no summary written
    return sizes


def test_the_header_schema_and_channel_are_on_disk_before_any_message(tmp_path: Path) -> None:
    path = tmp_path / "early.mcap"
    with path.open("wb") as stream:
        writer = RecordingWriter(stream)
        writer.add_channel("/level", "cdr", writer.add_schema(FLOAT, "ros2msg", b"float64 data"))
        # Not closed, nothing finished: what a process killed now leaves.
        kinds = []
        with path.open("rb") as on_disk:
            try:
                for record in StreamReader(on_disk).records:
                    kinds.append(type(record).__name__)
            except EndOfFile:  # the file ends there: no summary, no footer
                pass
    damages: list[Damage] = []
    assert list(read_recording(path, truncated=damages.append)) == []
    assert damages and damages[0].truncated, damages
    assert "without its summary" in damages[0].what
    assert {"Header", "Schema", "Channel"} <= set(kinds), kinds


def test_a_file_cut_anywhere_reads_up_to_its_last_whole_chunk_and_repairs_whole(
    tmp_path: Path,
) -> None:
    path = tmp_path / "killed.mcap"
    sizes = write_until_killed(path, messages=30, per_chunk=5)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    repaired = tmp_path / "repaired.mcap"
    for length in range(0, len(data) + 1, 7):
        cut.write_bytes(data[:length])
        damages: list[Damage] = []
        values = [m.message.data for m in read_recording(cut, truncated=damages.append)]
        # Every message of every chunk closed before the cut; the chunk the cut falls
        # after (in the message index that follows a chunk) too, none other.
        closed = sum(1 for size in sizes[1:] if size <= length)
        assert len(values) in (5 * closed, 5 * closed + 5), length
        assert values == [float(v) for v in range(len(values))], length
        assert len(damages) == 1 and damages[0].truncated, (length, damages)
        assert str(damages[0]).startswith(f"{cut}: byte ") and "truncated" in str(damages[0])
        if length < 8:
            continue  # not even the magic bytes: nothing to repair
        report = repair_recording(cut, repaired, replace=True)
        assert report.messages == len(values) and report.damage is not None
        # The upstream reader reads the repaired copy whole, through its summary too.
        with repaired.open("rb") as stream:
            upstream = list(make_reader(stream).iter_messages())
            assert len(upstream) == len(values), length
            stream.seek(0)
            summary = make_reader(stream).get_summary()
            assert summary is not None and summary.statistics is not None
            assert summary.statistics.message_count == len(values)
        with repaired.open("rb") as stream:
            list(StreamReader(stream, validate_crcs=True).records)


def test_contextros_repair_names_what_it_copied(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    write_until_killed(path, messages=12, per_chunk=5)
    with path.open("rb") as stream, pytest.raises(Exception):  # noqa: B017
        list(make_reader(stream).iter_messages())  # what the user met: the reader refuses it
    done = subprocess.run(
        [sys.executable, "-m", "contextros", "repair", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    output = tmp_path / "killed.repaired.mcap"
    assert done.stdout == f"repaired 10 messages, 9.0 s to {output} (/level: 10)\n"
    assert f"{path}: byte " in done.stderr and "truncated" in done.stderr
    with output.open("rb") as stream:
        assert len(list(make_reader(stream).iter_messages())) == 10
    again = subprocess.run(
        [sys.executable, "-m", "contextros", "repair", str(output), "-o", str(output)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert again.returncode == 2 and "must go to another file" in again.stderr
