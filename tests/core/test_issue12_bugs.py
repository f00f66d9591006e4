"""Regressions found by porting the peers' suites (issue 12): each failed before its fix."""

from __future__ import annotations

import asyncio
import contextvars
import gc
import sys
import threading

import pytest

from contextros import Layer, ProceedError, activate, activated, layered, proceed, set_active
from contextros.core import layered_function_of

Near, Far, Shared = Layer("Near"), Layer("Far"), Layer("Shared")


def helper_proceeding(x: int) -> int:
    """A helper the partial calls: it reaches the chain through `proceed` too."""
    return proceed(x) * 10


@layered
def measure(x: int) -> int:
    return x


@measure.partial(Near)
def measure(x: int) -> int:
    return helper_proceeding(x) + 1


@measure.partial(Far)
def measure(x: int) -> int:
    return 1000 + proceed(x)


def test_proceed_from_a_helper_function_reaches_the_next_implementation() -> None:
    activate(Near)
    assert measure(2) == 21
    activate(Far)  # Far outermost, then Near's helper proceeds to the base
    assert measure(2) == 1021


def test_proceed_from_a_helper_of_an_async_partial() -> None:
    @layered
    async def fetch() -> str:
        return "base"

    async def via_helper() -> str:
        return "helper>" + await proceed()

    @fetch.partial(Near)
    async def fetch() -> str:
        return "Near>" + await via_helper()

    activate(Near)
    assert asyncio.run(fetch()) == "Near>helper>base"


def test_proceed_from_a_helper_called_by_the_base_is_still_an_error() -> None:
    @layered
    def base_calls_helper() -> int:
        return helper_proceeding(1)

    @base_calls_helper.partial(Far)
    def base_calls_helper() -> int:
        return proceed()

    with pytest.raises(ProceedError):
        base_calls_helper()
    activate(Far)  # Far proceeds to the base, whose helper must not re-enter Far's chain
    with pytest.raises(ProceedError):
        base_calls_helper()


@layered
def where() -> str:
    return "base"


@where.partial(Near)
def where() -> str:
    return "near"


@where.partial(Far)
def where() -> str:
    return "far"


def test_every_thread_in_a_shared_scope_sees_each_decisive_switch_at_its_next_call() -> None:
    """Threads started inside one `with` block share its scope; a decisive switch made by
    one of them must be seen by the others at their next call, while they keep calling."""
    failures: list[str] = []
    stop = threading.Event()

    def hammer() -> None:
        while not stop.is_set():
            where()

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads often: the race needs no luck
    with activated(Shared):
        context = contextvars.copy_context()
        hammers = [threading.Thread(target=context.copy().run, args=(hammer,)) for _ in range(2)]
        for thread in hammers:
            thread.start()
        try:
            for round_ in range(200):
                layer, expected = (Near, "near") if round_ % 2 else (Far, "far")
                set_active([layer])
                seen: list[str] = []
                checker = threading.Thread(
                    target=context.copy().run, args=(lambda out=seen: out.append(where()),)
                )
                checker.start()
                checker.join(5)
                if seen != [expected]:
                    failures.append(f"round {round_}: {seen} after switching to {layer}")
        finally:
            stop.set()
            for thread in hammers:
                thread.join(5)
            sys.setswitchinterval(interval)
    assert not failures, failures[:5]


def test_the_direct_path_comes_back_after_a_task_held_scope_ends() -> None:
    set_active([Near])
    direct = where.__code__

    async def main() -> str:
        go = asyncio.Event()

        async def later() -> str:
            await go.wait()
            return where()

        with activated(Far):
            task = asyncio.create_task(later())
        go.set()
        return await task

    assert asyncio.run(main()) == "far"
    gc.collect()
    assert where() == "near"
    assert where.__code__ is direct  # the plain path again, not the scope-reading trampoline
    owner = layered_function_of(where)
    assert owner is not None


def test_a_head_composed_while_a_switch_happens_is_not_kept_for_the_new_configuration(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The interleaving behind the shared-scope bug, made deterministic: a thread in a
    shared scope composes its head for the old configuration, another thread switches
    meanwhile; the next call in the scope must run the new configuration."""
    owner = layered_function_of(where)
    assert owner is not None
    composing, switched = threading.Event(), threading.Event()
    original = owner.head_for
    slow_thread: list[threading.Thread] = []

    def head_for(configuration: tuple[Layer, ...]) -> object:
        head = original(configuration)
        if slow_thread and threading.current_thread() is slow_thread[0]:
            composing.set()
            switched.wait(5)  # the switch happens between composing and storing
        return head

    monkeypatch.setattr(owner, "head_for", head_for)
    set_active([Far])
    with activated(Shared):
        context = contextvars.copy_context()
        seen: list[str] = []
        worker = threading.Thread(target=context.run, args=(lambda: seen.append(where()),))
        slow_thread.append(worker)
        worker.start()
        assert composing.wait(5)
        set_active([Near])
        switched.set()
        worker.join(5)
        slow_thread.clear()
        assert seen == ["far"]  # that call began before the switch
        assert where() == "near"
