"""Layers the manager's own layer files declare (`contextros manager --layers`): known with
no participant implementing them, their relations checked, and a synchronous command whose
layers the manager applies itself (bindings) answered as applied by 0 nodes."""

from __future__ import annotations

from contextros.protocol import LayerDeclaration
from tests.protocol.manager.scenario import command, replies, report, started, states

# What `import-modes` writes for a system_modes model: layers that only carry bindings.
FILE = (
    LayerDeclaration("Slow", group="speed"),
    LayerDeclaration("Fast", group="speed"),
    LayerDeclaration("Docked", excludes=frozenset({"Fast"})),
    # A system's mode: no binding of its own, its parts' modes have some.
    LayerDeclaration("Rush", implies=frozenset({"Fast"})),
)
BOUND = frozenset({"Slow", "Fast"})  # Docked has no binding: nothing applies it


def test_a_layer_only_the_managers_file_declares_is_known_and_applied_by_0_nodes() -> None:
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    actions = command(manager, 1, 1.0, activate=("Slow",), synchronous=True)
    result = replies(actions)[1]
    assert result.success, result.message
    assert "applied by 0 node(s)" in result.message and "by the manager" in result.message
    assert [s.active for s in states(actions)] == [("Slow",)]
    # The file's exclusive group holds: Fast replaces Slow, and deactivating it succeeds.
    assert replies(command(manager, 2, 1.1, activate=("Fast",), synchronous=True))[2].success
    assert manager.state.active == ("Fast",)
    result = replies(command(manager, 3, 1.2, deactivate=("Fast",), synchronous=True))[3]
    assert result.success and manager.state.active == ()
    view = manager.registry(1.2)
    assert [d.name for d in view.layers] == ["Docked", "Fast", "Rush", "Slow"]
    assert view.implemented_by == {}


def test_the_files_relations_hold_for_its_own_layers() -> None:
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    command(manager, 1, 1.0, activate=("Fast",))
    result = replies(command(manager, 2, 1.1, activate=("Docked",)))[2]
    assert not result.success and "Docked excludes Fast" in result.message


def test_a_layer_implying_layers_the_manager_applies_is_applied_by_0_nodes() -> None:
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    result = replies(command(manager, 1, 1.0, activate=("Rush",), synchronous=True))[1]
    assert result.success, result.message
    assert manager.state.active == ("Fast", "Rush")
    result = replies(command(manager, 2, 1.1, deactivate=("Rush",), synchronous=True))[2]
    assert result.success and manager.state.active == ()
    # Asked again: no change, still a success (not "it reached no node").
    result = replies(command(manager, 3, 1.2, deactivate=("Rush",), synchronous=True))[3]
    assert result.success and "no change" in result.message


def test_a_layer_only_the_file_declares_is_the_managers_even_without_bindings() -> None:
    """Docked has no binding and no participant (a context flag rules set and read): the
    manager took it on its own word, so a synchronous command on it is applied by 0 nodes.
    (A newcomer: "epoch 8 not confirmed: it reached no node", exit 1, with Docked active.)"""
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    result = replies(command(manager, 1, 1.0, activate=("Docked",), synchronous=True))[1]
    assert result.success and "applied by 0 node(s)" in result.message, result.message
    assert manager.state.active == ("Docked",)
    result = replies(command(manager, 2, 1.1, deactivate=("Docked",), synchronous=True))[2]
    assert result.success and manager.state.active == ()


def test_a_file_layer_a_live_participant_implements_still_needs_its_acknowledgement() -> None:
    docked = LayerDeclaration("Docked")
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    manager.receive_status(report("/a", manager.state.epoch, layers=(docked,)), 1.0)
    actions = command(manager, 1, 1.05, activate=("Docked",), synchronous=True)
    assert 1 not in replies(actions), "answered before /a applied it"
    epoch = manager.state.epoch
    acked = manager.receive_status(report("/a", epoch, ("Docked",), layers=(docked,)), 1.1)
    assert replies(acked)[1].acknowledged == ("/a",)


def test_a_layer_nobody_declares_is_still_refused_naming_the_known_ones() -> None:
    manager = started(nodes=(), layer_files=FILE, applied_by_manager=BOUND)
    result = replies(command(manager, 1, 1.0, activate=("Slw",)))[1]
    assert not result.success
    assert "unknown layer 'Slw'" in result.message and "Docked, Fast, Rush, Slow" in result.message


def test_a_participant_still_acknowledges_its_layers_and_the_files() -> None:
    manager = started(nodes=("/a",), layer_files=FILE, applied_by_manager=BOUND)
    actions = command(manager, 1, 1.0, activate=("Slow",), synchronous=True)
    assert not replies(actions)  # /a is live: it must apply the epoch
    epoch = manager.state.epoch
    result = replies(manager.receive_status(report("/a", epoch, ("Slow",)), 1.1))[1]
    assert result.success and result.acknowledged == ("/a",)
    assert manager.registry(1.1).implemented_by["Indoor"] == ("/a",)
