"""`contextros repair` on a recording damaged inside, and on an output file that exists."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mcap_ros2")
from mcap.reader import make_reader

from contextros.recording import RecordingError
from contextros.recording.repair import repair_recording
from tests.recording.test_writer import write_until_killed


def damaged(path: Path) -> int:
    """A recording of 30 messages in chunks of 5 whose third chunk is damaged (a byte of
    its data changed): where that chunk begins."""
    sizes = write_until_killed(path, messages=30, per_chunk=5)
    data = bytearray(path.read_bytes())
    data[sizes[2] + 70] ^= 0xFF
    path.write_bytes(bytes(data))
    return sizes[2]


def repair(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "contextros", "repair", *arguments],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_repair_stops_at_the_first_damaged_record_and_says_how_much_came_before(
    tmp_path: Path,
) -> None:
    """What comes after the damage, whole chunks too, is not copied (docs/observability.md);
    the damage counts the messages copied before it."""
    path, output = tmp_path / "bad.mcap", tmp_path / "bad.repaired.mcap"
    broken_at = damaged(path)
    report = repair_recording(path, output)
    assert report.damage is not None and report.damage.offset == broken_at
    assert not report.damage.truncated and "damaged record" in report.damage.what
    assert (report.messages, report.damage.messages) == (10, 10)
    with output.open("rb") as stream:
        assert len(list(make_reader(stream).iter_messages())) == 10


def test_repair_does_not_replace_an_existing_file_unless_forced(tmp_path: Path) -> None:
    path, output = tmp_path / "killed.mcap", tmp_path / "kept.mcap"
    write_until_killed(path, messages=12, per_chunk=5)
    output.write_bytes(b"someone's file")
    with pytest.raises(RecordingError, match="exists already"):
        repair_recording(path, output)
    refused = repair(str(path), "-o", str(output))
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr == (
        f"contextros repair: {output} exists already: not replaced (--force replaces it)\n"
    )
    assert output.read_bytes() == b"someone's file"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    forced = repair(str(path), "-o", str(output), "--force")
    assert forced.returncode == 0, forced.stderr
    with output.open("rb") as stream:
        assert len(list(make_reader(stream).iter_messages())) == 10
