"""The manager's state file on disk: a write that fails leaves no partial file behind, and
a write that succeeds is durable, its rename included (the directory fsynced)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from contextros.protocol import LayerState, ManagerMemory
from contextros.ros.manager_node import StateFile


def test_a_failed_write_leaves_the_old_file_and_no_partial_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    state_file = StateFile(tmp_path / "state.json")
    state_file.save(LayerState(3, ("Indoor",), "me", "why"))

    def full_disk(descriptor: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(OSError, match="No space left"):
        state_file.save(LayerState(4, ("Outdoor",), "me", "why"))
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]
    memory = state_file.load()
    assert isinstance(memory, ManagerMemory) and memory.state.epoch == 3


def test_a_write_fsyncs_the_file_and_then_its_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    synced: list[str] = []
    real_fsync = os.fsync

    def recording_fsync(descriptor: int) -> None:
        synced.append(os.readlink(f"/proc/self/fd/{descriptor}"))
        real_fsync(descriptor)

    monkeypatch.setattr(os, "fsync", recording_fsync)
    StateFile(tmp_path / "state.json").save(LayerState(5, (), "me", ""))
    assert len(synced) == 2, synced
    assert synced[0].startswith(str(tmp_path / ".state.json.")), synced
    assert synced[1] == str(tmp_path), "the rename is on disk only once the directory is"
