"""A manager and participant processes, started together, plus registry polling."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from contextros.protocol import ManagerError
from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup

LIVENESS = "1.0"  # seconds: the tests' manager drops silent participants fast


@dataclass
class RunningSystem:
    manager: Child
    participants: dict[str, Child]


def start_system(
    group: ProcessGroup,
    client: LayerClient,
    names: Sequence[str],
    *manager_args: str,
) -> RunningSystem:
    """Start participants and a manager at once (processes start in parallel) and wait
    until the manager has finished recovery with every participant registered."""
    participants = {name: group.participant(name) for name in names}
    manager = group.manager("--liveness-timeout", LIVENESS, *manager_args)
    for child in participants.values():
        child.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    wait_for_manager(client, manager)
    wanted = {f"/{name}" for name in names}
    wait_registry(
        client,
        lambda r: r.epoch >= 1 and {p.node for p in r.participants} >= wanted,
        what=f"participants {sorted(wanted)} registered",
    )
    return RunningSystem(manager, participants)


def wait_for_manager(client: LayerClient, manager: Child, timeout: float = 15.0) -> None:
    """`client.wait_for_manager`, failing with what the manager process printed (and its
    exit status, if it ended)."""
    try:
        client.wait_for_manager(timeout)
    except ManagerError as error:
        ended = manager.popen.poll()
        how = "still running" if ended is None else f"exit status {ended}"
        raise AssertionError(f"{error}; the manager ({how}) printed:\n{manager.output()}") from None


def wait_registry(
    client: LayerClient,
    predicate: Callable[[Any], bool],
    timeout: float = 10.0,
    what: str = "",
    show: Sequence[Child] = (),
) -> Any:
    """The registry once `predicate` holds; on a timeout, fails with it and the last lines
    the processes `show` printed."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            registry = client.query(timeout=1.0)
        except ManagerError:  # a (re)starting manager is not discovered yet
            if time.monotonic() > deadline:
                raise
            continue
        if predicate(registry):
            return registry
        if time.monotonic() > deadline:
            nodes = [(p.node, p.applied_epoch) for p in registry.participants]
            raise AssertionError(
                f"timed out waiting for {what}: epoch {registry.epoch}, "
                f"active {list(registry.active_layers)}, participants {nodes}, "
                f"manager {registry.manager_id} (recovering: {registry.recovering})"
                + "".join(
                    f"\n--- {child.name} printed:\n" + "\n".join(child.lines[-20:])
                    for child in show
                )
            )
        time.sleep(0.05)


def settle(client: LayerClient, *layers: str) -> Any:
    """Make exactly `layers` active (in this order), whatever earlier tests left behind,
    once the manager has its first state (a recovering manager publishes one when done)."""
    current = list(wait_registry(client, lambda r: not r.recovering, what="recovery").active_layers)
    if current != list(layers):
        cleared = client.request([], current, synchronous=True, timeout=5)
        assert cleared.success, cleared.message
        if layers:
            result = client.request(layers, synchronous=True, timeout=5)
            assert result.success, result.message
    return client.query()
