"""Partials and their analysis are published together, as one snapshot: a call composing
its chain on the scoped or per-receiver path (without the runtime's lock) while another
thread adds, replaces or removes partials sees one consistent set and never caches a
chain of a replaced partial."""

from __future__ import annotations

import sys
import threading
from typing import Any

from contextros import Layer, activate_for, activated, deactivate_for, layered, proceed

LAYERS = [Layer(f"Snapshot{i}") for i in range(6)]


def _adds(amount: int) -> Any:
    def partial(self: object) -> int:
        return proceed(self) + amount  # type: ignore[no-any-return]

    return partial


def test_calls_racing_partial_changes_compose_from_one_consistent_snapshot() -> None:
    class Robot:
        @layered
        def speed(self) -> int:
            return 1

    r = Robot()
    activate_for(r, *LAYERS)
    stop = threading.Event()
    errors: list[BaseException] = []

    def on_receiver() -> None:
        while not stop.is_set():
            try:
                r.speed()
            except BaseException as error:
                errors.append(error)

    def in_scope() -> None:
        other = Robot()
        with activated(*LAYERS):
            while not stop.is_set():
                try:
                    other.speed()
                except BaseException as error:
                    errors.append(error)

    callers = [threading.Thread(target=on_receiver) for _ in range(2)]
    callers.append(threading.Thread(target=in_scope))
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads often: the race needs no luck
    try:
        for thread in callers:
            thread.start()
        for round_ in range(40):
            for layer in LAYERS:
                Robot.speed.partial(layer, replace=True)(_adds(round_))  # type: ignore[attr-defined]
            for layer in LAYERS[1:]:
                Robot.speed.remove_partial(layer)  # type: ignore[attr-defined]
            deactivate_for(r, LAYERS[0])  # fresh receiver tables: chains composed again
            activate_for(r, LAYERS[0])
    finally:
        stop.set()
        for thread in callers:
            thread.join()
        sys.setswitchinterval(interval)
    assert errors == []
    # A replaced partial runs from the next composition on: no chain of an older one was kept.
    Robot.speed.partial(LAYERS[0], replace=True)(_adds(100))  # type: ignore[attr-defined]
    deactivate_for(r, LAYERS[0])
    activate_for(r, LAYERS[0])
    assert r.speed() == 101
