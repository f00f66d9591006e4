"""Scoped activation (per thread and asyncio task), hooks, observers, critical sections."""

from __future__ import annotations

import asyncio
import threading

import pytest

from contextros import (
    HookError,
    Layer,
    RelationError,
    SwitchEvent,
    activate,
    activated,
    active_layers,
    critical,
    current_epoch,
    deactivate,
    deactivated,
    layered,
    proceed,
    subscribe,
    switch,
)

Indoor = Layer("Indoor", group="location")
Outdoor = Layer("Outdoor", group="location")
Night = Layer("Night")


@layered
def mode() -> str:
    return "base"


@mode.partial(Indoor)
def mode() -> str:
    return "indoor"


@mode.partial(Outdoor)
def mode() -> str:
    return "outdoor"


@mode.partial(Night)
def mode() -> str:
    return "night/" + proceed()


def names() -> list[str]:
    return [layer.name for layer in active_layers()]


def test_scoped_activation_holds_for_the_block_only() -> None:
    with activated(Indoor) as configuration:
        assert configuration == (Indoor,)
        assert mode() == "indoor"
        with activated(Night):
            assert mode() == "night/indoor"
        with deactivated(Indoor):
            assert mode() == "base"
    assert mode() == "base" and names() == []


def test_scoped_group_member_hides_the_decisive_one() -> None:
    activate(Indoor)
    with activated(Outdoor):
        assert mode() == "outdoor"
    assert mode() == "indoor"


def test_scoped_relation_violation_is_rejected_on_entry() -> None:
    Layer("Lonely", requires=["Company"])
    with pytest.raises(RelationError, match="Lonely requires Company"), activated("Lonely"):
        pass
    assert mode() == "base"


def test_scopes_are_per_thread() -> None:
    inside, release = threading.Event(), threading.Event()
    seen: dict[str, str] = {}

    def worker() -> None:
        with activated(Outdoor):
            inside.set()
            release.wait(5)
            seen["worker"] = mode()

    thread = threading.Thread(target=worker)
    thread.start()
    assert inside.wait(5)
    seen["main"] = mode()
    release.set()
    thread.join(5)
    assert seen == {"worker": "outdoor", "main": "base"}


def test_scopes_are_per_asyncio_task_and_follow_decisive_switches() -> None:
    async def in_scope(layer: Layer, started: asyncio.Event, go: asyncio.Event) -> str:
        with activated(layer):
            started.set()
            await go.wait()
            return mode()

    async def plain(go: asyncio.Event) -> str:
        await go.wait()
        return mode()

    async def main() -> list[str]:
        go = asyncio.Event()
        s1, s2 = asyncio.Event(), asyncio.Event()
        tasks = [
            asyncio.create_task(in_scope(Night, s1, go)),
            asyncio.create_task(in_scope(Outdoor, s2, go)),
            asyncio.create_task(plain(go)),
        ]
        await s1.wait()
        await s2.wait()
        activate(Indoor)  # decisive switch while the scopes are open
        go.set()
        return list(await asyncio.gather(*tasks))

    assert asyncio.run(main()) == ["night/indoor", "outdoor", "indoor"]


def test_task_created_in_a_scope_keeps_it_after_the_block_ends() -> None:
    async def main() -> str:
        go = asyncio.Event()

        async def later() -> str:
            await go.wait()
            return mode()

        with activated(Outdoor):
            task = asyncio.create_task(later())
        assert mode() == "base"
        go.set()
        return await task

    assert asyncio.run(main()) == "outdoor"
    assert mode() == "base"


def test_hooks_run_in_the_documented_order() -> None:
    order: list[str] = []

    def hook(text: str, layer: str | None = None) -> object:
        def run() -> None:
            current = [layer.name for layer in active_layers()]
            order.append(f"{text} active={current}")

        return run

    Layer("H1", on_activate=hook("+H1"), on_deactivate=hook("-H1"))
    Layer("H2", on_activate=hook("+H2"), on_deactivate=hook("-H2"))
    Layer("H3", on_activate=hook("+H3"), on_deactivate=hook("-H3"))
    activate("H1", "H2")
    switch(activate=["H3"], deactivate=["H1", "H2"])
    assert order == [
        "+H1 active=['H1', 'H2']",
        "+H2 active=['H1', 'H2']",
        "-H2 active=['H1', 'H2']",  # deactivation hooks: newest first, layer still active
        "-H1 active=['H1', 'H2']",
        "+H3 active=['H3']",
    ]


def test_failing_deactivate_hook_abandons_the_switch() -> None:
    def refuse() -> None:
        raise ValueError("still wiping")

    Layer("Sticky", on_deactivate=refuse)
    activate("Sticky")
    epoch = current_epoch()
    with pytest.raises(HookError, match="on_deactivate hook of layer Sticky failed: still wiping"):
        deactivate("Sticky")
    assert names() == ["Sticky"] and current_epoch() == epoch


def test_failing_activate_hook_keeps_the_consistent_new_state() -> None:
    def broken() -> None:
        raise ValueError("no lidar")

    Layer("Fragile", on_activate=broken)
    with pytest.raises(HookError, match="on_activate hook of layer Fragile") as caught:
        activate("Fragile")
    assert isinstance(caught.value.__cause__, ValueError)
    assert names() == ["Fragile"]


def test_observers_see_every_applied_switch_with_increasing_epochs() -> None:
    events: list[SwitchEvent] = []
    unsubscribe = subscribe(events.append)
    activate(Indoor)
    activate(Outdoor)
    activate(Outdoor)  # no change: no event
    with pytest.raises(RelationError):
        switch(activate=[Indoor], deactivate=[Indoor])
    unsubscribe()
    deactivate(Outdoor)
    assert [(e.old, e.new) for e in events] == [((), (Indoor,)), ((Indoor,), (Outdoor,))]
    assert events[1].epoch == events[0].epoch + 1
    assert events[1].activated == (Outdoor,) and events[1].deactivated == (Indoor,)


def test_critical_section_defers_switches_and_applies_them_in_order() -> None:
    events: list[tuple[str, ...]] = []
    subscribe(lambda e: events.append(tuple(layer.name for layer in e.new)))
    with critical():
        first = activate(Indoor)
        second = activate(Night)
        assert first.deferred and not first.done
        assert mode() == "base" and names() == []
    assert first.wait(0) and second.wait(0)
    assert second.epoch == first.epoch + 1  # type: ignore[operator]
    assert events == [("Indoor",), ("Indoor", "Night")]
    assert mode() == "night/indoor"


def test_critical_section_blocks_switches_from_other_threads_until_it_ends() -> None:
    results = []
    with critical():
        thread = threading.Thread(target=lambda: results.append(activate(Outdoor)))
        thread.start()
        thread.join(5)
        assert results[0].deferred and mode() == "base"
        assert not results[0].wait(0.05)
    assert results[0].wait(1) and mode() == "outdoor"


def test_deferred_switch_that_became_invalid_is_rejected_not_raised() -> None:
    Layer("Needy", requires=["Helper"])
    Layer("Helper")
    activate("Helper")
    with critical():
        off = deactivate("Helper")
        needy = activate("Needy")
    assert off.applied
    assert not needy.applied and isinstance(needy.error, RelationError)
    assert names() == []


def test_nested_critical_sections_release_at_the_outermost_end() -> None:
    with critical():
        with critical():
            pending = activate(Night)
        assert not pending.done
    assert pending.applied


def test_decisive_switch_inside_an_open_scope_shows_through_at_once() -> None:
    with activated(Night):
        assert mode() == "night/base"
        activate(Outdoor)
        assert mode() == "night/outdoor"
        activate(Indoor)
        assert mode() == "night/indoor"
    assert mode() == "indoor"


def test_in_critical_section_reports_open_sections() -> None:
    from contextros import in_critical_section

    assert not in_critical_section()
    with critical():
        assert in_critical_section()
    assert not in_critical_section()
