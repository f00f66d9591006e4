"""Synchronous activations: who must acknowledge, and an honest answer naming who did not."""

from __future__ import annotations

import pytest

from tests.protocol.manager.scenario import (
    System,
    command,
    replies,
    report,
    started,
    states,
)


def test_sync_activation_waits_for_every_live_participant() -> None:
    system = System()
    actions = system.command(1, activate=("Indoor",), synchronous=True)
    assert states(actions) and not replies(actions)
    assert not replies(system.ack("/a"))
    assert not replies(system.ack("/b"))
    result = replies(system.ack("/c"))[1]
    assert result.success
    assert result.acknowledged == ("/a", "/b", "/c") and result.not_acknowledged == ()
    assert "epoch 2" in result.message


def test_sync_timeout_names_the_nodes_that_did_not_acknowledge() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True, timeout=1.0)
    system.ack("/a")
    system.feed(
        system.manager.receive_status(
            report("/b", 1, pending_epoch=2, in_critical_section=True), system.now
        )
    )
    system.advance(0.5)
    system.heartbeat_all(except_=("/a", "/b"))
    result = replies(system.advance(0.6))[1]
    assert not result.success
    assert result.acknowledged == ("/a",)
    assert result.not_acknowledged == ("/b", "/c")
    assert (
        "/b (in a critical section" in result.message and "/c (still on epoch 0)" in result.message
    )
    assert result.elapsed == pytest.approx(1.1)


def test_failure_to_apply_is_reported_at_once() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.ack("/a")
    system.ack("/b")
    status = report("/c", 1, failed_epoch=2, error="epoch 2: hook of Night raised")
    result = replies(system.feed(system.manager.receive_status(status, system.now)))[1]
    assert (
        not result.success
        and "/c (failed to apply: epoch 2: hook of Night raised)" in result.message
    )


def test_a_newer_state_also_acknowledges_older_pending_activations() -> None:
    system = System()
    system.command(1, activate=("Night",), synchronous=True)
    system.command(2, activate=("Indoor",), synchronous=True)
    for node in ("/a", "/b"):
        system.ack(node)
    done = replies(system.ack("/c"))
    assert done[1].success and done[2].success
    assert (done[1].epoch, done[2].epoch) == (2, 3)


def test_sync_with_no_change_confirms_the_current_epoch() -> None:
    system = System()
    for node in ("/a", "/b", "/c"):
        system.ack(node)
    actions = system.command(1, deactivate=("Night",), synchronous=True)
    assert states(actions) == [] and replies(actions)[1].success


def test_one_participant_speaks_for_the_other_nodes_of_its_process() -> None:
    system = System(nodes=("/host", "/solo"))
    system.feed(
        system.manager.receive_status(report("/host", hosted=("/guest1", "/guest2")), system.now)
    )
    view = system.manager.registry(system.now)
    assert {p.node: p.hosted for p in view.participants} == {
        "/host": ("/guest1", "/guest2"),
        "/solo": (),
    }
    system.command(1, activate=("Indoor",), synchronous=True)
    assert not replies(system.ack("/solo"))  # still waiting for /host (and so its guests)
    result = replies(system.ack("/host", hosted=("/guest1", "/guest2")))[1]
    assert result.success and "applied by 4 node(s)" in result.message
    assert result.acknowledged == ("/guest1", "/guest2", "/host", "/solo")


def test_a_synchronous_answer_carries_its_own_epochs_active_layers() -> None:
    manager = started(("/a",))
    first = states(command(manager, 1, 1.0, activate=("Indoor",), synchronous=True))[0]
    command(manager, 2, 1.0, activate=("Night",))  # another client, before the ack
    assert manager.state.active == ("Indoor", "Night")
    result = replies(manager.receive_status(report("/a", 3, ("Indoor", "Night")), 1.1))[1]
    assert result.success and result.epoch == first.epoch
    assert result.active == ("Indoor",), "the answer shows epoch 2's layers, not epoch 3's"


def test_a_deactivation_that_reaches_nobody_fails() -> None:
    manager = started(("/a",))
    command(manager, 1, 1.0, activate=("Night",))
    manager.receive_status(report("/a", leaving=True), 1.1)
    result = replies(command(manager, 2, 1.2, deactivate=("Night",), synchronous=True))[2]
    assert not result.success and "reached no node" in result.message
    assert result.acknowledged == ()


def test_expected_nodes_must_apply_even_when_they_were_dropped_before() -> None:
    manager = started(("/local", "/remote"))
    manager.receive_status(report("/local", 1), 1.5)
    manager.tick(3.2)  # /remote silent: dropped before the command
    assert manager.live_nodes == ("/local",)
    actions = command(
        manager,
        1,
        3.3,
        activate=("Night",),
        synchronous=True,
        timeout=1.0,
        expect_nodes=("/local", "/remote"),
    )
    assert not replies(actions), "/local acknowledging alone is not enough"
    assert not replies(manager.receive_status(report("/local", 3, ("Night",)), 3.4))
    result = replies(manager.tick(4.4))[1]
    assert not result.success
    assert result.acknowledged == ("/local",) and result.not_acknowledged == ("/remote",)
    assert "expected node /remote did not apply it" in result.message


def test_an_expected_node_that_rejoins_in_time_makes_it_a_success() -> None:
    manager = started(("/local",))
    command(manager, 1, 1.0, activate=("Night",), synchronous=True, expect_nodes=("/remote",))
    manager.receive_status(report("/local", 2, ("Night",)), 1.1)
    assert not replies(manager.receive_status(report("/remote", 0), 1.2))
    result = replies(manager.receive_status(report("/remote", 2, ("Night",)), 1.3))[1]
    assert result.success and result.acknowledged == ("/local", "/remote")


def test_an_expected_count_counts_hosted_nodes() -> None:
    manager = started(("/host",))
    command(manager, 1, 1.0, activate=("Night",), synchronous=True, timeout=1.0, expect_count=3)
    reply = replies(manager.receive_status(report("/host", 2, hosted=("/g1",)), 1.1))
    assert reply == {}, "two nodes so far"
    result = replies(manager.tick(2.1))[1]
    assert not result.success and "applied by 2 node(s), 3 expected" in result.message
    command(manager, 2, 2.2, activate=("Indoor",), synchronous=True, expect_count=2)
    result = replies(manager.receive_status(report("/host", 3, hosted=("/g1",)), 2.3))[2]
    assert result.success and result.acknowledged == ("/g1", "/host")
