"""The bounded explorer (contextros.protocol.explorer): every interleaving of the real
protocol up to a depth keeps every guarantee, a state reached twice is explored once, a
manager breaking a guarantee is caught with a shortest trace, and what the protocol is
known to break shows (`make explore` runs a larger bound, printing the same)."""

from __future__ import annotations

import pickle
from dataclasses import replace

import pytest

from contextros.protocol.explorer import (
    SCRIPT,
    Bounds,
    Exploration,
    explore,
    fingerprint,
    initial_world,
    main,
)
from contextros.protocol.invariants import (
    ALL,
    PROPOSAL_EPOCHS,
    SYNC_NAMES_KNOWN,
    InvariantViolation,
)
from tests.protocol.broken_managers import (
    ForgetsParticipants,
    ForgetsProposals,
    ReusesEpochs,
    WaitsForOneNode,
)

ATOMIC_VETOED, ATOMIC, SYNCHRONOUS = SCRIPT


def _clean(result: Exploration) -> Exploration:
    assert result.violation is None, result.summary()
    assert result.depth == result.bounds.depth
    return result


def test_a_small_bound_keeps_every_guarantee() -> None:
    """2 participants, 3 commands in any order, a node crash, a manager restart: depth 5."""
    result = _clean(explore(Bounds(depth=5)))
    assert result.states > 5_000 and result.transitions > result.states


def test_three_participants_keep_every_guarantee() -> None:
    result = _clean(explore(Bounds(participants=3, depth=4)))
    assert result.states > 2_000


def test_a_state_reached_by_two_orders_is_one_state() -> None:
    bounds = Bounds()
    world = initial_world(bounds)
    world.apply(("command", 2), bounds)  # the synchronous one: a state to each node
    first, second = list(world.network)
    frozen = pickle.dumps(world)

    def after(*messages: object) -> int:
        copy = pickle.loads(frozen)
        for message in messages:
            copy.apply(("deliver", message), bounds)
        return fingerprint(copy)

    assert after(first, second) == after(second, first)
    assert after(first) != after(second) != after(first, second)
    assert after() == fingerprint(world)


@pytest.mark.parametrize(
    ("bounds", "complaint", "steps"),
    [
        # A command publishing its change under epoch 1 again.
        (Bounds(depth=3, manager_class=ReusesEpochs), "names two layer sets", 1),
        # The synchronous command, its state to one node, its status back, a tick.
        (
            Bounds(
                depth=5,
                commands=(SYNCHRONOUS,),
                node_crashes=0,
                manager_restarts=0,
                manager_class=WaitsForOneNode,
            ),
            "live when it arrived",
            4,
        ),
    ],
)
def test_a_broken_manager_is_caught_with_a_shortest_trace(
    bounds: Bounds, complaint: str, steps: int
) -> None:
    result = explore(bounds)
    assert result.violation is not None
    assert complaint in str(result.violation)
    assert len(result.trace) == steps
    assert f"VIOLATION at depth {steps}" in result.summary()


def test_a_manager_reusing_a_proposed_epoch_after_a_crash_is_caught() -> None:
    """Issue 24 item 1 as it was: the explorer finds it in 4 events."""
    bounds = Bounds(depth=5, commands=(ATOMIC,), node_crashes=0, manager_class=ForgetsProposals)
    result = explore(bounds)
    assert isinstance(result.violation, InvariantViolation)
    assert result.violation.invariant == PROPOSAL_EPOCHS
    assert [step.split(":")[0] for step in reversed(result.trace)] == [
        "command reaches the manager",
        "crash manager",
        "restart the manager from its state file",
        "time moves to 2 s",
    ]
    steps = result.summary().splitlines()
    assert steps[-1].startswith("  4. time moves") and "proposed by manager m1" in steps[1]


def test_the_real_manager_never_reuses_a_proposed_epoch() -> None:
    """The same bound, one event deeper, with the real manager."""
    _clean(explore(Bounds(depth=5, commands=(ATOMIC,), node_crashes=0)))


def test_the_command_line_prints_states_depth_and_time(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--depth", "2"]) == 0
    out = capsys.readouterr().out
    assert " states (" in out and "to depth 2 in " in out and ": no violation" in out


# -- larger bounds (make test-slow; `make explore` prints them) -----------------------------


@pytest.mark.slow
@pytest.mark.parametrize(("participants", "depth"), [(2, 6), (3, 5)])
def test_a_larger_bound_keeps_every_guarantee(participants: int, depth: int) -> None:
    _clean(explore(Bounds(participants=participants, depth=depth)))


@pytest.mark.slow
def test_the_first_sync_after_a_restart_waits_for_the_nodes_known_before() -> None:
    """Issue 24 item 2: found in 7 events as it was (the synchronous command alone, a
    manager restart); the real manager keeps it to the same depth."""
    bounds = Bounds(depth=7, commands=(SYNCHRONOUS,), node_crashes=0)
    broken = explore(replace(bounds, manager_class=ForgetsParticipants))
    assert broken.violation is not None and len(broken.trace) == 7
    assert broken.violation.invariant == SYNC_NAMES_KNOWN
    _clean(explore(bounds))


@pytest.mark.slow
def test_a_node_is_asked_to_veto_a_proposal_once() -> None:
    """Issue 24 item 4: before a node remembered the newest proposal it voted on per
    manager, 7 events broke it (an atomic activation vetoed and timed out, another
    proposed, the first proposal delivered again)."""
    bounds = Bounds(
        depth=7, commands=(ATOMIC_VETOED, ATOMIC), node_crashes=0, manager_restarts=0, checked=ALL
    )
    _clean(explore(bounds))
