"""A hierarchy three levels deep on real processes (issue 28, item 1): Mission implies
Airborne; Airborne implies Propulsion and CameraHigh. Three nodes, each implementing a part
(one in C++), the relations declared by the nodes that implement the layers. Activating
Mission with `contextros activate --sync` reaches every node with all four layers;
`status` says what implies what; deactivating Mission takes out what it alone implied."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import RunningSystem, settle, wait_registry
from tests.ros.test_cli import contextros

NODES = ("/drone", "/motors", "/camera")
HIERARCHY = ["CameraHigh", "Propulsion", "Airborne", "Mission"]


@pytest.fixture(scope="module")
def system(client: LayerClient) -> Iterator[RunningSystem]:
    group = ProcessGroup()
    try:
        participants = {
            "drone": group.participant("drone", "--layers", "Mission,Airborne"),
            "motors": group.participant("motors", "--layers", "Propulsion"),
            # The C++ node declares Survey implies CameraHigh.
            "camera": group.cpp_participant("camera", "--layers", "CameraHigh,CameraLow,Survey"),
        }
        manager = group.manager("--liveness-timeout", "2.0")
        for child in participants.values():
            child.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
        client.wait_for_manager(15.0)
        wait_registry(
            client,
            lambda r: {p.node for p in r.participants} >= set(NODES),
            what="the three nodes",
        )
        yield RunningSystem(manager, participants)
    finally:
        group.kill_all()


def test_activating_the_top_of_a_hierarchy_reaches_every_node_with_every_level(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client)
    done = contextros("activate", "Mission", "--sync", "--timeout", "10", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["active"] == HIERARCHY
    assert set(answer["acknowledged"]) >= set(NODES)
    for child in system.participants.values():
        assert child.wait_applied(answer["epoch"])["active"] == HIERARCHY

    status = json.loads(contextros("status", "--json").stdout)
    assert status["implied_by"] == {
        "Airborne": ["Mission"],
        "CameraHigh": ["Airborne"],
        "Propulsion": ["Airborne"],
    }
    airborne = next(layer for layer in status["layers"] if layer["name"] == "Airborne")
    assert airborne["implies"] == ["CameraHigh", "Propulsion"]
    text = contextros("status").stdout
    assert (
        "active [CameraHigh (implied by Airborne), Propulsion (implied by Airborne), "
        "Airborne (implied by Mission), Mission]" in text
    )

    refused = client.request([], ["Propulsion"], synchronous=True, timeout=5)
    assert not refused.success
    assert "Propulsion is implied by Airborne, which stays active" in refused.message

    done = contextros("deactivate", "Mission", "--sync", "--timeout", "10", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["active"] == []
    for child in system.participants.values():
        assert child.wait_applied(answer["epoch"])["active"] == []


def test_a_layer_asked_for_on_its_own_stays_when_its_implier_leaves(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client)
    for layer in ("Propulsion", "Mission"):
        assert client.request([layer], synchronous=True, timeout=5).success
    done = contextros("deactivate", "Mission", "--sync", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["active"] == ["Propulsion"]
    assert system.participants["motors"].wait_applied(answer["epoch"])["active"] == ["Propulsion"]


def test_a_cpp_node_declares_what_its_layer_implies(
    system: RunningSystem, client: LayerClient
) -> None:
    settle(client)
    registry = client.query()
    survey = next(layer for layer in registry.layers if layer.name == "Survey")
    assert list(survey.implies) == ["CameraHigh"]
    done = contextros("activate", "Survey", "--sync", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    assert answer["active"] == ["CameraHigh", "Survey"]
    camera = system.participants["camera"].wait_applied(answer["epoch"])
    assert camera["active"] == ["CameraHigh", "Survey"]
    # The C++ node's CameraHigh and a CameraLow asked for: one group, Survey keeps CameraHigh.
    refused = contextros("activate", "CameraLow", "--sync")
    assert refused.returncode != 0
    assert "group 'camera' allows one active layer" in refused.stderr
    assert "CameraHigh implied by Survey" in refused.stderr


def test_watch_shows_what_implies_what(system: RunningSystem, client: LayerClient) -> None:
    settle(client)
    group = ProcessGroup()
    try:
        watch = group.start("watch", ["-m", "contextros", "watch", "--count", "1", "--json"])
        watch.wait_for(
            lambda events: (
                {e.get("node") for e in events if e["event"] == "node"} >= set(NODES)
                and any(e["event"] == "current" for e in events)
            ),
            10,
            "the current state and the three nodes",
        )
        result = client.request(["Mission"], synchronous=True, timeout=5)
        assert result.success, result.message
        assert watch.wait_exit(10) == 0
        state = next(e for e in watch.events if e["event"] == "state")
        assert state["epoch"] == result.epoch and state["active"] == HIERARCHY
        assert state["implied_by"] == {
            "Airborne": ["Mission"],
            "CameraHigh": ["Airborne"],
            "Propulsion": ["Airborne"],
        }
    finally:
        group.kill_all()
