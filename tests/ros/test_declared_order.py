"""The declared `after` order across the ROS system: a participant announces it, the manager
composes in it, `activate` warns where the requested order contradicts it, `status` says so."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import RunningSystem, settle, wait_registry
from tests.ros.test_cli import contextros


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        participants = {
            "rescue": group.participant("rescue", "--layers", "Rubble,Flight,Flooded,Night")
        }
        manager = group.manager("--liveness-timeout", "1.0")
        participants["rescue"].wait_for(
            lambda events: any(e["event"] == "ready" for e in events), 15, "ready"
        )
        client.wait_for_manager(15.0)
        yield RunningSystem(manager, participants)
    finally:
        group.kill_all()


def test_activate_in_a_contradicting_order_warns_and_composes_as_declared(
    system: RunningSystem, client: LayerClient
) -> None:
    wait_registry(client, lambda r: any(p.node == "/rescue" for p in r.participants))
    settle(client)
    done = contextros("activate", "Rubble", "Flight", "Flooded", "--sync", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["active"] == ["Flight", "Flooded", "Rubble"], "Rubble is not hidden"
    assert "composed as declared: Rubble after Flooded" in answer["message"]
    assert "warning: activation order Rubble, Flight, Flooded contradicts" in done.stderr
    applied = system.participants["rescue"].wait_applied(answer["epoch"])
    assert applied["active"] == ["Flight", "Flooded", "Rubble"]
    shown = contextros("status")
    assert "composed in the declared order (last = outermost): Rubble after Flooded" in (
        shown.stdout
    )
    status = json.loads(contextros("status", "--json").stdout)
    rubble = next(layer for layer in status["layers"] if layer["name"] == "Rubble")
    assert rubble["after"] == ["Flooded"]


def test_an_agreeing_order_gives_no_warning(system: RunningSystem, client: LayerClient) -> None:
    settle(client)
    done = contextros("activate", "Flooded", "Rubble", "--sync")
    assert done.returncode == 0, done.stderr
    assert "warning" not in done.stderr
    assert "active [Flooded, Rubble]" in done.stdout
