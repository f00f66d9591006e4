"""Whatever the network does to states (reorder, duplicate, drop all but the last), no
participant goes back to an older epoch and every one ends on the manager's last state."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from contextros.protocol import (
    ActivationCommand,
    ApplyState,
    LayerDeclaration,
    LayerState,
    ManagerProtocol,
    ManagerSettings,
    ParticipantProtocol,
    ParticipantReport,
    PublishState,
)

LAYERS = (
    LayerDeclaration("Indoor", group="location"),
    LayerDeclaration("Outdoor", group="location"),
    LayerDeclaration("Night"),
    LayerDeclaration("Gps", requires=frozenset({"Outdoor"})),
)
NAMES = [d.name for d in LAYERS]
commands = st.lists(
    st.tuples(
        st.lists(st.sampled_from(NAMES), max_size=2), st.lists(st.sampled_from(NAMES), max_size=2)
    ),
    min_size=1,
    max_size=25,
)


@settings(max_examples=150, deadline=None)
@given(commands=commands, deliveries=st.randoms(use_true_random=False))
def test_no_regression_and_convergence_under_reordering(
    commands: list[tuple[list[str], list[str]]], deliveries: random.Random
) -> None:
    manager = ManagerProtocol(0.0, ManagerSettings(recovery_window=0.0))
    participants = [ParticipantProtocol(f"/p{i}", "1", LAYERS) for i in range(3)]
    for p in participants:
        manager.receive_status(p.report(), 0.0)
    published: list[LayerState] = [
        a.state for a in manager.tick(0.0) if isinstance(a, PublishState)
    ]
    for index, (on, off) in enumerate(commands):
        command = ActivationCommand(index, activate=tuple(on), deactivate=tuple(off))
        published += [
            a.state for a in manager.receive_command(command, 0.1) if isinstance(a, PublishState)
        ]
    epochs = [s.epoch for s in published]
    assert epochs == sorted(set(epochs)), "the manager's epochs strictly increase"

    for p in participants:
        # Each participant sees an arbitrary shuffled, duplicated subset, then the last state.
        inbox = [s for s in published if deliveries.random() < 0.7] * deliveries.randint(1, 2)
        deliveries.shuffle(inbox)
        applied: list[int] = []
        for state in [*inbox, published[-1]]:
            for action in p.receive_state(state):
                assert isinstance(action, ApplyState)
                p.applied(action.state, 0.2)
                applied.append(action.state.epoch)
        assert applied == sorted(set(applied)), f"{p.node} went back: {applied}"
        assert (p.applied_epoch, p.active) == (manager.state.epoch, manager.state.active)
        report = p.report()
        assert isinstance(report, ParticipantReport) and report.applied_epoch == epochs[-1]
