"""Parts of the manager's ROS adapter: its state file on disk (a write that fails leaves no
partial file behind; one that succeeds is durable, its rename included) and the answers it
holds back (every one sent when it steps down)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

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


def test_a_manager_that_steps_down_answers_every_command_still_awaited() -> None:
    """`_DeferredResponses.answer_all`: each held request answered once with the reason,
    whether the executor already handed its response over or not."""
    from contextros_interfaces.srv import Activate

    from contextros.protocol import ActivationResult
    from contextros.ros.manager_node import _DeferredResponses

    sent: list[tuple[Any, str]] = []

    class Service:
        def send_response(self, response: Any, header: str) -> None:
            sent.append((response, header))

    service = Service()
    responses = _DeferredResponses(service, lambda error: None)
    held, fresh = Activate.Response(), Activate.Response()
    responses.expect(1, held)
    responses.expect(2, fresh)
    service.send_response(held, "header-1")  # the executor handed #1 over: held back
    assert sent == []
    responses.answer_all(ActivationResult(False, "stepped down", 7, ("Indoor",)))
    assert [(r.success, r.message, h) for r, h in sent] == [(False, "stepped down", "header-1")]
    service.send_response(fresh, "header-2")  # #2's callback returns only now: filled in
    assert [h for _, h in sent] == ["header-1", "header-2"] and sent[1][0].epoch == 7
    responses.answer_all(ActivationResult(False, "again", 7, ()))
    assert len(sent) == 2, "answered once"
