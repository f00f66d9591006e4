"""Callers on many threads see the old chain or the new one, never a mix."""

from __future__ import annotations

import threading

from contextros import Layer, activated, layered, proceed, set_active

P, Q, R = Layer("P"), Layer("Q"), Layer("R")


@layered
def stack() -> tuple[str, ...]:
    return ()


@stack.partial(P)
def stack() -> tuple[str, ...]:
    return ("P", *proceed())


@stack.partial(Q)
def stack() -> tuple[str, ...]:
    return ("Q", *proceed())


@stack.partial(R)
def stack() -> tuple[str, ...]:
    return ("R", *proceed())


CONFIGURATIONS = [[P, Q, R], [], [R, P], [Q], [P, Q, R]]
VALID = {tuple(layer.name for layer in reversed(c)) for c in CONFIGURATIONS}


def test_concurrent_calls_never_observe_a_half_applied_switch() -> None:
    stop = threading.Event()
    seen: set[tuple[str, ...]] = set()
    errors: list[BaseException] = []

    def caller(scoped: bool) -> None:
        try:
            while not stop.is_set():
                if scoped:  # exercises the context-variable dispatch path too
                    with activated(Q):
                        seen.add(stack())
                seen.add(stack())
        except BaseException as error:  # pragma: no cover - reported below
            errors.append(error)

    threads = [threading.Thread(target=caller, args=(i == 0,)) for i in range(4)]
    for thread in threads:
        thread.start()
    for _ in range(300):
        for configuration in CONFIGURATIONS:
            set_active(configuration)
    stop.set()
    for thread in threads:
        thread.join(10)
    assert not errors
    scoped_variants = {
        tuple(layer.name for layer in reversed([x for x in c if x != Q] + [Q]))
        for c in CONFIGURATIONS
    }
    assert seen <= VALID | scoped_variants
    assert len(seen & VALID) >= 2  # the callers really ran across switches


def test_leaving_the_last_scope_restores_the_direct_path() -> None:
    from contextros.core import layered_function_of

    owner = layered_function_of(stack)
    assert owner is not None
    set_active([P])
    direct = stack.__code__
    with activated(Q):
        assert stack.__code__ is not direct
        assert stack() == ("Q", "P")
    assert stack.__code__ is direct
    assert stack() == ("P",)
