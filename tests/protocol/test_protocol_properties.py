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
    Reply,
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


TICK = 0.05
events = st.lists(
    st.one_of(
        st.tuples(st.just("command"), st.sampled_from(NAMES), st.booleans(), st.booleans()),
        st.tuples(st.just("ack"), st.integers(0, 2), st.booleans()),
        st.tuples(st.just("wait"), st.floats(0.05, 1.5)),
        st.tuples(st.just("die"), st.integers(0, 2)),
    ),
    max_size=40,
)


@settings(max_examples=200, deadline=None)
@given(script=events)
def test_every_synchronous_command_gets_one_honest_answer_in_time(script: list[tuple]) -> None:  # type: ignore[type-arg]
    settings_ = ManagerSettings(
        liveness_timeout=1.0, default_timeout=2.0, recovery_window=0.0, unknown_layer_grace=0.0
    )
    manager = ManagerProtocol(0.0, settings_)
    now = 0.0
    nodes = [f"/p{i}" for i in range(3)]
    alive = dict.fromkeys(nodes, True)
    applied = dict.fromkeys(nodes, 0)
    for node in nodes:
        manager.receive_status(ParticipantReport(node, "1", LAYERS), now)
    manager.tick(now)
    asked: dict[int, tuple[float, bool, set[str]]] = {}  # id -> (deadline, synchronous, live)
    # live: the nodes live when it was asked, and those that rejoined while it was pending
    answered: dict[int, object] = {}
    last_epoch = manager.state.epoch

    def collect(actions: list[object]) -> None:
        nonlocal last_epoch
        for action in actions:
            if isinstance(action, PublishState):
                assert action.state.epoch == last_epoch + 1
                last_epoch = action.state.epoch
            if isinstance(action, Reply):
                assert action.request_id not in answered, "answered twice"
                answered[action.request_id] = action.result
                result = action.result
                deadline, synchronous, live = asked[action.request_id]
                assert set(result.acknowledged) | set(result.not_acknowledged) <= live
                assert now <= deadline + TICK + 1e-9, "answered at the first tick past the timeout"
                for node in result.acknowledged:
                    assert applied[node] >= result.epoch, "acknowledged without applying"
                if result.success and synchronous:
                    assert set(result.acknowledged) == live
                    assert result.acknowledged, "a success reached at least one node"

    for request_id, event in enumerate(script):
        if event[0] == "command":
            _, layer, activate, synchronous = event
            command = ActivationCommand(
                request_id,
                activate=(layer,) if activate else (),
                deactivate=() if activate else (layer,),
                synchronous=synchronous,
            )
            live = {n for n in nodes if n in manager.live_nodes}
            asked[request_id] = (now + settings_.default_timeout, synchronous, live)
            collect(manager.receive_command(command, now))
        elif event[0] == "ack":
            _, index, fresh = event
            node = nodes[index]
            if alive[node]:
                if fresh:
                    applied[node] = manager.state.epoch
                report = ParticipantReport(node, "1", LAYERS, applied_epoch=applied[node])
                if node not in manager.live_nodes:  # it rejoins: a pending command counts it
                    for pending in set(asked) - set(answered):
                        asked[pending][2].add(node)
                collect(manager.receive_status(report, now))
        elif event[0] == "wait":
            end = now + event[1]
            while now < end:  # the adapter ticks every 50 ms
                now = min(end, now + TICK)
                collect(manager.tick(now))
        else:
            alive[nodes[event[1]]] = False
    end = now + settings_.default_timeout + settings_.liveness_timeout + 0.1
    while now < end:
        now += TICK
        collect(manager.tick(now))
    synchronous_ids = {i for i, e in enumerate(script) if e[0] == "command" and e[3]}
    asynchronous_ids = {i for i, e in enumerate(script) if e[0] == "command" and not e[3]}
    assert synchronous_ids | asynchronous_ids == set(answered), "every command is answered"
