"""Layers that imply layers (issue 28, item 1), in the manager: activating a layer activates
what it implies, transitively; deactivating it removes what it alone implied; contradicting
declarations from the nodes are refused naming the layers; the state file keeps which
layers were asked for across a restart."""

from __future__ import annotations

import pytest

from contextros.protocol import (
    ActivationCommand,
    LayerDeclaration,
    ManagerProtocol,
    ManagerSettings,
    ParticipantReport,
    PublishProposal,
    PublishState,
    Reply,
)
from contextros.protocol.errors import StateFileError
from contextros.protocol.relations import (
    explicit_roots,
    implication_problems,
    implied_by,
    implied_layers,
    merge_declarations,
)
from contextros.protocol.state import ManagerMemory

SETTINGS = ManagerSettings(recovery_window=1.0, unknown_layer_grace=0.0)


def layer(name: str, group: str = "", **relations: str) -> LayerDeclaration:
    fields = {key: frozenset(value.split()) for key, value in relations.items()}
    return LayerDeclaration(name, group=group, **fields)  # type: ignore[arg-type]


# A drone: Mission implies Flight; Flight implies Propulsion and CameraHigh (three levels).
DRONE = (
    layer("Mission", implies="Flight"),
    layer("Flight", group="mode", implies="Propulsion CameraHigh"),
    layer("Landed", group="mode", implies="CameraLow"),
    layer("Propulsion"),
    layer("CameraHigh", group="camera"),
    layer("CameraLow", group="camera"),
    layer("Lights"),
)


def manager(*layers: LayerDeclaration, memory: ManagerMemory | None = None) -> ManagerProtocol:
    protocol = ManagerProtocol(0.0, SETTINGS, memory)
    protocol.receive_status(ParticipantReport("/a", "1", layers=layers), 0.0)
    protocol.tick(2.0)
    return protocol


def run(
    protocol: ManagerProtocol, activate: str = "", deactivate: str = "", atomic: bool = False
) -> tuple[tuple[str, ...], str, bool]:
    command = ActivationCommand(
        1, activate=tuple(activate.split()), deactivate=tuple(deactivate.split()), atomic=atomic
    )
    actions = protocol.receive_command(command, 2.0)
    reply = next((a.result for a in actions if isinstance(a, Reply)), None)
    if atomic and reply is None:  # every target votes yes
        proposal = next(a.state for a in actions if isinstance(a, PublishProposal))
        vote = ParticipantReport(
            "/a",
            "1",
            layers=DRONE,
            applied_epoch=protocol.state.epoch,
            vote_epoch=proposal.epoch,
            vote_manager_id=protocol.settings.manager_id,
            vote_yes=True,
        )
        actions = protocol.receive_status(vote, 2.0)
        ack = ParticipantReport("/a", "1", layers=DRONE, applied_epoch=proposal.epoch)
        actions += protocol.receive_status(ack, 2.0)
        reply = next(a.result for a in actions if isinstance(a, Reply))
    assert reply is not None
    return protocol.state.active, reply.message, reply.success


def test_activating_a_layer_activates_what_it_implies_three_levels_deep() -> None:
    protocol = manager(*DRONE)
    active, _, success = run(protocol, "Mission")
    assert success
    assert active == ("CameraHigh", "Propulsion", "Flight", "Mission"), "parts inside"
    assert protocol.explicit == ("Mission",)
    assert implied_by(active, protocol.declarations()) == {
        "CameraHigh": ("Flight",),
        "Flight": ("Mission",),
        "Propulsion": ("Flight",),
    }


def test_deactivating_removes_what_it_alone_implied() -> None:
    protocol = manager(*DRONE)
    run(protocol, "Propulsion")  # asked for on its own: stays
    run(protocol, "Mission")
    active, _, success = run(protocol, deactivate="Mission")
    assert success
    assert active == ("Propulsion",)
    assert protocol.explicit == ("Propulsion",)


def test_a_layer_implied_by_another_active_layer_stays() -> None:
    declarations = (*DRONE, layer("Survey", implies="CameraHigh"))
    protocol = manager(*declarations)
    run(protocol, "Flight Survey")
    active, _, _ = run(protocol, deactivate="Flight")
    assert active == ("CameraHigh", "Survey"), "Survey still implies CameraHigh"


def test_an_implied_layer_cannot_be_deactivated_alone() -> None:
    protocol = manager(*DRONE)
    run(protocol, "Mission")
    before = protocol.state
    _, message, success = run(protocol, deactivate="Propulsion")
    assert not success and protocol.state == before
    assert "Propulsion is implied by Flight, which stays active" in message


def test_a_group_switch_takes_the_implied_layers_along() -> None:
    protocol = manager(*DRONE)
    run(protocol, "Landed")
    active, _, success = run(protocol, "Flight")
    assert success
    assert active == ("CameraHigh", "Propulsion", "Flight"), "CameraLow left with Landed"


def test_an_implied_layer_displaces_an_explicit_member_of_its_group() -> None:
    protocol = manager(*DRONE)
    run(protocol, "CameraLow")
    active, _, success = run(protocol, "Flight")
    assert success and "CameraLow" not in active


def test_an_implied_layer_meeting_another_implied_one_of_its_group_is_refused() -> None:
    declarations = (*DRONE, layer("Inspect", implies="CameraLow"))
    protocol = manager(*declarations)
    run(protocol, "Flight")
    before = protocol.state
    _, message, success = run(protocol, "Inspect")
    assert not success and protocol.state == before
    assert "group 'camera' allows one active layer" in message
    assert "CameraHigh implied by Flight" in message and "CameraLow implied by Inspect" in message


def test_implied_layers_satisfy_requires_and_follow_the_declared_order() -> None:
    declarations = (
        layer("Flight", implies="Propulsion", requires="Propulsion"),
        layer("Propulsion", after="Flight"),
    )
    protocol = manager(*declarations)
    active, message, success = run(protocol, "Flight")
    assert success and active == ("Flight", "Propulsion")
    assert "Propulsion after Flight" in message


def test_an_implied_layer_an_active_layer_excludes_is_refused() -> None:
    protocol = manager(*DRONE, layer("Quiet", excludes="Propulsion"))
    run(protocol, "Quiet")
    _, message, success = run(protocol, "Mission")
    assert not success
    assert "Quiet excludes Propulsion" in message and "Propulsion implied by Flight" in message


def test_contradicting_declarations_from_two_nodes_are_refused_naming_the_layers() -> None:
    protocol = manager(*DRONE)
    # Another node declares Flight to imply the low camera too: two of group 'camera'.
    other = ParticipantReport("/b", "1", layers=(layer("Flight", implies="CameraLow"),))
    protocol.receive_status(other, 2.0)
    active, message, success = run(protocol, "Mission")
    assert not success and active == ()
    assert "Flight implies CameraHigh and CameraLow, both in exclusive group 'camera'" in message


def test_contradictions_named() -> None:
    declarations = merge_declarations(
        [
            layer("A", implies="B", excludes="C"),
            layer("B", implies="C D"),
            layer("C"),
            layer("D", excludes="B"),
            layer("E", implies="F"),
            layer("F", implies="E"),
        ]
    )
    problems = implication_problems("A", declarations)
    assert "A implies C, and A excludes C" in problems
    assert "B implies D, and D excludes B" in problems
    assert implication_problems("E", declarations) == [
        "the declared 'implies' of E, F form a cycle"
    ]
    assert implied_layers("A", declarations) == ("C", "D", "B")


def test_a_cycle_of_implies_is_refused() -> None:
    protocol = manager(layer("E", implies="F"), layer("F", implies="E"))
    active, message, success = run(protocol, "E")
    assert not success and active == ()
    assert "'implies' of E, F form a cycle" in message


def test_an_implied_layer_nobody_implements_is_unknown() -> None:
    protocol = manager(layer("Flight", implies="Propulsion"))
    _, message, success = run(protocol, "Flight")
    assert not success
    assert "unknown layer 'Propulsion' (implied by Flight)" in message


def test_an_atomic_activation_commits_what_it_asked_for() -> None:
    protocol = manager(*DRONE)
    active, _, success = run(protocol, "Mission", atomic=True)
    assert success and active == ("CameraHigh", "Propulsion", "Flight", "Mission")
    assert protocol.explicit == ("Mission",)


def test_the_state_file_keeps_what_was_asked_for_across_a_restart() -> None:
    protocol = manager(*DRONE)
    run(protocol, "Propulsion")
    run(protocol, "Mission")
    memory = ManagerMemory.from_json(protocol.memory().to_json())
    assert memory.explicit == ("Propulsion", "Mission")
    restarted = manager(*DRONE, memory=memory)
    active, _, _ = run(restarted, deactivate="Mission")
    assert active == ("Propulsion",), "asked for explicitly before the restart: stays"


def test_an_old_state_file_reads_as_every_layer_asked_for() -> None:
    old = '{"epoch": 3, "active": ["Propulsion", "Flight"], "requester": "", "reason": ""}'
    memory = ManagerMemory.from_json(old)
    assert memory.explicit is None
    restarted = manager(*DRONE, memory=memory)
    assert restarted.explicit == ("Propulsion", "Flight")


def test_a_damaged_explicit_field_is_named() -> None:
    text = '{"epoch": 3, "active": ["Flight"], "explicit": ["Nope"]}'
    with pytest.raises(StateFileError, match="field 'explicit' must list active layers"):
        ManagerMemory.from_json(text, "state.json")


def test_without_memory_the_layers_no_other_implies_count_as_asked_for() -> None:
    declarations = merge_declarations(DRONE)
    roots = explicit_roots(("Propulsion", "CameraHigh", "Flight", "Lights"), declarations)
    assert roots == ("Flight", "Lights")


def test_activating_an_implied_layer_explicitly_keeps_it_after_its_implier_leaves() -> None:
    protocol = manager(*DRONE)
    run(protocol, "Flight")
    before = protocol.state.epoch
    _, message, success = run(protocol, "Propulsion")
    assert success and protocol.state.epoch == before and message == "no change"
    active, _, _ = run(protocol, deactivate="Flight")
    assert active == ("Propulsion",)


def test_published_states_are_full_snapshots_with_the_implied_layers() -> None:
    protocol = manager(*DRONE)
    actions = protocol.receive_command(ActivationCommand(1, activate=("Mission",)), 2.0)
    published = [a.state.active for a in actions if isinstance(a, PublishState)]
    assert published == [("CameraHigh", "Propulsion", "Flight", "Mission")]


def test_a_long_chain_from_the_network_is_no_recursion_and_a_long_cycle_is_named() -> None:
    chain = [layer(f"L{i}", implies=f"L{i + 1}") for i in range(5000)] + [layer("L5000")]
    declarations = merge_declarations(chain)
    assert len(implied_layers("L0", declarations)) == 5000
    assert implication_problems("L0", declarations) == []
    looped = merge_declarations([*chain[:-1], layer("L5000", implies="L1")])
    (problem,) = implication_problems("L0", looped)
    assert problem.startswith("the declared 'implies' of L1, L10, L100,")
    assert problem.endswith(" and 4990 more form a cycle"), "answers stay small"
    assert "L0," not in problem, "L0 leads into the cycle but is not on it"


def test_implies_from_the_network_is_checked_like_every_relation() -> None:
    from contextros.protocol.validation import MAX_RELATIONS, declaration_problems

    bad = LayerDeclaration("Flight", implies=frozenset({"not a name"}))
    assert declaration_problems(bad) == [
        "layer 'Flight' implies entry 'not a name' is not an identifier"
    ]
    many = LayerDeclaration("Flight", implies=frozenset(f"P{i}" for i in range(MAX_RELATIONS + 1)))
    (problem,) = declaration_problems(many)
    assert f"more than {MAX_RELATIONS}" in problem
    protocol = manager(*DRONE)
    epoch = protocol.state.epoch
    protocol.receive_status(ParticipantReport("/evil", "1", layers=(bad,)), 2.0)
    assert "Flight" in protocol.declarations() and protocol.state.epoch == epoch
    assert protocol.declarations()["Flight"].implies == {"Propulsion", "CameraHigh"}


def test_an_explicit_mark_that_publishes_nothing_is_written_before_its_answer() -> None:
    """`activate Flight` while Mission implies it: "no change" on the wire, but Flight is now
    asked for on its own. A newcomer killed the manager after that answer: the state file
    still said only Mission, and the restarted manager dropped Flight with Mission."""
    from contextros.protocol.adapter_model import state_file

    protocol = manager(*DRONE)
    run(protocol, "Mission")
    saved = protocol.memory()
    actions = protocol.receive_command(ActivationCommand(2, activate=("Flight",)), 2.0)
    assert not any(isinstance(a, PublishState) for a in actions), "nothing published"
    written = state_file(saved, protocol, actions)
    assert written is not None and set(written.explicit or ()) == {"Mission", "Flight"}
    restarted = manager(*DRONE, memory=ManagerMemory.from_json(written.to_json()))
    active, _, _ = run(restarted, deactivate="Mission")
    assert active == ("CameraHigh", "Propulsion", "Flight")
