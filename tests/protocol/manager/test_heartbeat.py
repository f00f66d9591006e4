"""The manager's heartbeat, and the repeats of a new state on it for lossy links."""

from __future__ import annotations

from contextros.protocol import (
    ManagerProtocol,
    ManagerSettings,
    PublishHeartbeat,
)
from tests.protocol.manager.scenario import (
    command,
    report,
    started,
    states,
)


def test_a_new_state_is_repeated_on_the_heartbeat_shortly_after() -> None:
    manager = started(("/a",))
    manager.tick(1.3)
    (state,) = states(command(manager, 1, 1.31, activate=("Night",)))
    beats = []
    for step in range(1, 12):
        now = 1.31 + step * 0.05
        beats += [
            (round(now, 2), a.state.epoch)
            for a in manager.tick(now)
            if isinstance(a, PublishHeartbeat)
        ]
    assert beats[:2] == [(1.36, state.epoch), (1.46, state.epoch)]
    assert all(epoch == state.epoch for _, epoch in beats)
    assert len(beats) >= 3, "and every heartbeat period after that"


def test_no_repeat_once_every_node_has_the_state() -> None:
    manager = started(("/a",))
    manager.tick(1.3)
    (state,) = states(command(manager, 1, 1.31, activate=("Night",)))
    manager.receive_status(report("/a", state.epoch, ("Night",)), 1.33)
    beats = [
        round(now, 2)
        for now in (1.36, 1.41, 1.46, 1.51, 1.56, 1.61)
        for a in manager.tick(now)
        if isinstance(a, PublishHeartbeat)
    ]
    assert beats == [1.56], "only the regular heartbeat, 0.25 s after the last one"


def test_a_running_manager_that_published_nothing_beats_with_its_id() -> None:
    # No state file, nobody heard: no state yet, but another manager must hear this one.
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=1.0, manager_id="m1"))
    beats = [a for a in manager.tick(1.0) + manager.tick(1.3) if isinstance(a, PublishHeartbeat)]
    assert states(manager.tick(1.31)) == []
    assert beats and all(b.state.manager_id == "m1" for b in beats)
    assert beats[-1].state.epoch == 0 and beats[-1].state.reason != "recovering"
