"""What a manager with a state file keeps across a crash (issue 24): the highest epoch it
proposed, the participants it knew; and the deadlines of commands that wait."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from contextros.protocol import (
    ActivationCommand,
    KnownParticipant,
    LayerState,
    ManagerMemory,
    ManagerProtocol,
    PublishProposal,
    StateFileError,
)
from tests.protocol.manager.scenario import SETTINGS, replies, report, states


def test_the_memory_reads_back_what_it_wrote_and_an_old_file_reads_as_none() -> None:
    memory = ManagerMemory(
        LayerState(4, ("Indoor",), "me", "why"), 6, (KnownParticipant("/a", "i1", ("/h",)),)
    )
    assert ManagerMemory.from_json(memory.to_json()) == memory
    old = LayerState(4, ("Indoor",)).to_json()
    assert ManagerMemory.from_json(old) == ManagerMemory(LayerState(4, ("Indoor",)))
    with pytest.raises(StateFileError, match="proposed_epoch"):
        ManagerMemory.from_json(old.replace("{", '{"proposed_epoch": "7",', 1))
    with pytest.raises(StateFileError, match="node name"):
        ManagerMemory.from_json(
            old.replace("{", '{"participants": [{"node": 3, "incarnation": ""}],', 1)
        )


def test_an_epoch_proposed_before_a_crash_is_skipped_by_the_next_manager() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    manager.tick(1.0)  # epoch 1
    actions = manager.receive_command(ActivationCommand(1, ("Night",), atomic=True), 1.1)
    proposal = next(a.state for a in actions if isinstance(a, PublishProposal))
    memory = manager.memory()
    assert memory.proposed_epoch == proposal.epoch == 2
    assert memory.participants == (KnownParticipant("/a", "1"),)
    # The crash: a new manager from that memory.
    successor = ManagerProtocol(10.0, SETTINGS, memory)
    successor.receive_status(report("/a", applied=1), 10.1)
    first = states(successor.tick(11.0))
    assert [s.epoch for s in first] == [3], "epoch 2 named [Night] in the vote"


def test_a_restarted_manager_waits_for_the_participants_it_knew() -> None:
    known = (KnownParticipant("/a", "1"), KnownParticipant("/b", "1"))
    manager = ManagerProtocol(0.0, SETTINGS, ManagerMemory(LayerState(5), 5, known))
    manager.tick(1.0)  # recovery over with nobody heard: epoch 6
    manager.receive_status(report("/a", applied=6), 1.1)
    actions = manager.receive_command(ActivationCommand(1, ("Night",), synchronous=True), 1.2)
    actions += manager.receive_status(report("/a", applied=7, active=("Night",)), 1.3)
    assert 1 not in replies(actions), "answered while /b, known before, was not heard"
    actions = manager.receive_status(report("/b", applied=7, active=("Night",)), 1.4)
    assert replies(actions)[1].acknowledged == ("/a", "/b")
    # One that never comes back is dropped a liveness bound after recovery, and named.
    late = ManagerProtocol(0.0, SETTINGS, ManagerMemory(LayerState(5), 5, known))
    late.tick(1.0)
    late.receive_status(report("/a", applied=6), 1.1)
    pending = late.receive_command(ActivationCommand(3, ("Night",), synchronous=True), 1.2)
    pending += late.receive_status(report("/a", applied=7, active=("Night",)), 1.3)
    pending += late.tick(1.0 + SETTINGS.liveness_timeout + 0.1)
    result = replies(pending)[3]
    assert not result.success and "/b (dropped, not heard for" in result.message


def test_a_command_still_waiting_at_its_deadline_is_refused_never_executed() -> None:
    manager = ManagerProtocol(0.0, replace(SETTINGS, recovery_window=3.0))
    manager.receive_status(report("/a"), 0.0)
    assert manager.receive_command(ActivationCommand(1, ("Night",), timeout=1.0), 0.1) == []
    refused = replies(manager.tick(1.2))[1]
    assert (
        not refused.success and "not started within the command's timeout (1 s)" in refused.message
    )
    after = manager.tick(10.0)
    assert all("Night" not in s.active for s in states(after))


def test_a_command_whose_ros_side_started_in_time_is_carried_through_past_its_deadline() -> None:
    """The adapter set its parameters (seconds) and hands it on after its deadline: refused
    now, ROS would go there and back. One it kept waiting is refused saying for what."""
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    manager.tick(1.0)
    command = ActivationCommand(1, ("Night",), timeout=1.0)
    actions = manager.receive_command(command, now=4.0, received=1.1, started=True)
    assert [s.active for s in states(actions)] == [("Night",)]
    assert replies(actions)[1].success
    kept = ActivationCommand(2, ("Day",), timeout=1.0)
    assert manager.refusal_if_expired(kept, 1.5, 1.1, "behind a drive") == []
    refused = replies(manager.refusal_if_expired(kept, 2.2, 1.1, "behind a drive"))[2]
    assert not refused.success and "(behind a drive); nothing changed" in refused.message


def test_an_abort_names_every_node_that_says_no() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    for node in ("/a", "/b", "/c"):
        manager.receive_status(report(node), 0.0)
    manager.tick(1.0)
    actions = manager.receive_command(ActivationCommand(1, ("Night",), atomic=True), 1.1)
    epoch = next(a.state for a in actions if isinstance(a, PublishProposal)).epoch
    vote = {"vote_epoch": epoch, "vote_manager_id": SETTINGS.manager_id, "applied": 1}
    no_a = manager.receive_status(report("/a", vote_yes=False, vote_reason="busy", **vote), 1.2)
    assert 1 not in replies(no_a), "aborted before every vote was in"
    manager.receive_status(report("/b", vote_yes=True, **vote), 1.3)
    result = replies(manager.receive_status(report("/c", vote_reason="no", **vote), 1.4))[1]
    assert result.not_acknowledged == ("/a", "/c")
    assert "/a vetoed: busy" in result.message and "/c vetoed: no" in result.message


def test_expect_count_counts_a_node_that_joins_during_the_command() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    manager.receive_status(report("/a"), 0.0)
    manager.tick(1.0)
    command = ActivationCommand(1, (), ("Indoor",), synchronous=True, expect_count=2)
    manager.receive_command(ActivationCommand(9, ("Indoor",)), 1.0)
    actions = manager.receive_command(command, 1.1)
    actions += manager.receive_status(report("/a", applied=3), 1.2)
    actions += manager.receive_status(report("/b", applied=0), 1.3)  # joins
    actions += manager.receive_status(report("/b", applied=3), 1.4)
    assert replies(actions)[1].acknowledged == ("/a", "/b")


def test_a_node_that_rejoins_during_a_synchronous_command_is_waited_for() -> None:
    manager = ManagerProtocol(0.0, SETTINGS)
    for node in ("/a", "/b", "/c"):
        manager.receive_status(report(node), 0.0)
    manager.tick(1.0)  # epoch 1
    manager.receive_status(report("/a", applied=1), 2.0)
    manager.receive_status(report("/b", applied=1), 2.0)
    manager.tick(3.5)  # /c silent for 3.5 s: dropped
    assert "/c" in manager.dropped
    actions = manager.receive_command(ActivationCommand(1, ("Night",), synchronous=True), 3.6)
    actions += manager.receive_status(report("/c", applied=1), 3.7)  # back
    actions += manager.receive_status(report("/a", applied=2, active=("Night",)), 3.8)
    actions += manager.receive_status(report("/b", applied=2, active=("Night",)), 3.9)
    assert 1 not in replies(actions), "answered 'every node' while /c, back, had not applied"
    actions = manager.receive_status(report("/c", applied=2, active=("Night",)), 4.0)
    assert replies(actions)[1].acknowledged == ("/a", "/b", "/c")


def _corpus(directory: Path) -> list[tuple[Path, str]]:
    """Damaged state files, each with what the message must say is wrong."""
    good = ManagerMemory(
        LayerState(4, ("Indoor",), "me", "why"), 6, (KnownParticipant("/a", "i1", ("/h",)),)
    ).to_json()
    fields = json.loads(good)
    files: list[tuple[str, bytes | None, str]] = [
        ("empty", b"", "it is empty"),
        ("binary", bytes(range(256)), "not UTF-8 at byte 128"),
        ("latin1", good.replace("me", "m\xe9").encode("latin-1"), "not UTF-8 at byte"),
        ("list", b'[{"epoch": 4, "active": []}]', "not a JSON object but a list"),
        ("number", b"7", "not a JSON object but a number"),
        ("null", b"null", "not a JSON object but null"),
        ("deep", b"[" * 100_000, "not JSON"),
        ("huge-number", b'{"epoch": ' + b"9" * 5000 + b"}", "not JSON (a number of 5000 digits)"),
        ("directory", None, "it is a directory"),
    ]
    files += [
        (f"cut-{at}", good[:at].encode(), "not JSON at line ")
        for at in (1, 2, len(good) // 3, len(good) // 2, len(good) - 1)
    ]
    for key in ("epoch", "active"):
        missing = {k: v for k, v in fields.items() if k != key}
        files.append((f"no-{key}", json.dumps(missing).encode(), f"missing field {key!r}"))
    wrong = {
        "epoch": ("3", "field 'epoch' must be a non-negative integer, not a string ('3')"),
        "active": ("Indoor", "field 'active' must be a list of layer names, not a string"),
        "requester": (5, "field 'requester' must be a string, not a number (5)"),
        "reason": ([], "field 'reason' must be a string, not a list"),
        "stamp": ({}, "field 'stamp' must be a number, not an object"),
        "proposed_epoch": (None, "field 'proposed_epoch' must be an integer, not null"),
        "participants": ({}, "field 'participants' must be a list, not an object"),
    }
    for key, (value, message) in wrong.items():
        files.append((f"wrong-{key}", json.dumps(fields | {key: value}).encode(), message))
    files += [
        (
            "participant-list",
            json.dumps(fields | {"participants": [[]]}).encode(),
            "a participant must be a JSON object, not a list",
        ),
        (
            "participant-no-node",
            json.dumps(fields | {"participants": [{"incarnation": "1"}]}).encode(),
            "missing field 'node'",
        ),
        (
            "participant-hosted",
            json.dumps(
                fields | {"participants": [{"node": "/a", "incarnation": "1", "hosted": [1]}]}
            ).encode(),
            "participant /a: hosted nodes must be a list of names",
        ),
    ]
    made = []
    for name, content, message in files:
        path = directory / f"{name}.json"
        if content is None:
            path.mkdir()
        else:
            path.write_bytes(content)
        made.append((path, message))
    return made


def test_every_damaged_state_file_is_one_clear_message_naming_the_file(tmp_path: Path) -> None:
    for path, message in _corpus(tmp_path):
        with pytest.raises(StateFileError) as refused:
            ManagerMemory.read(path)
        text = str(refused.value)
        assert text.startswith(f"{path}: not a ContextROS state file: "), text
        assert message in text, (message, text)
        # No Python internals: exception names, a repr of the parser's own words.
        assert not any(word in text for word in ("Error", "indices", "file ('", "object has")), text
    assert ManagerMemory.read(tmp_path / "absent.json") is None
