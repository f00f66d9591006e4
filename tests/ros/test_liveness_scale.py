"""Liveness at scale on real processes (issue 26): beyond `--status-rate` statuses per second
the manager asks its participants (Python and C++) for a longer heartbeat period, and drops
a silent one after as many periods as its liveness timeout is at 0.25 s."""

from __future__ import annotations

import signal
import time

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import wait_registry


def test_a_slower_heartbeat_keeps_live_nodes_and_a_dead_one_is_dropped_after_the_longer_bound(
    client: LayerClient, processes: ProcessGroup
) -> None:
    # 2 participants at --status-rate 2: 8 statuses/s at 0.25 s is beyond 2, so the manager
    # asks for 1.25 * 2 / 2 = 1.25 s and drops after 0.6 * 1.25 / 0.25 = 3 s of silence.
    python = processes.participant("slow_py")
    cpp = processes.cpp_participant("slow_cpp")
    processes.manager("--liveness-timeout", "0.6", "--status-rate", "2")
    both = {"/slow_py", "/slow_cpp"}
    wait_registry(
        client,
        lambda r: {p.node for p in r.participants} == both,
        timeout=20,
        what="both joined",
        show=(python, cpp),
    )
    time.sleep(1.5)  # both have heard the period and sent on it
    silent = dict.fromkeys(both, 0.0)
    for _ in range(25):  # 2.5 s: each reports once or twice (once every 0.25 s before)
        for participant in client.query().participants:
            silent[participant.node] = max(silent[participant.node], participant.silent_for)
        time.sleep(0.1)
    assert min(silent.values()) > 0.7, f"longest silences seen: {silent}"
    assert {p.node for p in client.query().participants} == both, "silent > 0.6 s, not dropped"
    python.signal(signal.SIGKILL)
    killed = time.monotonic()
    registry = wait_registry(
        client, lambda r: "/slow_py" in r.dropped, timeout=10, what="/slow_py dropped"
    )
    elapsed = time.monotonic() - killed
    # The bound (3 s) less the time since its last heartbeat (up to 1.25 s), plus ticks.
    assert 1.5 < elapsed < 4.5, f"dropped {elapsed:.2f} s after its death"
    assert [p.node for p in registry.participants] == ["/slow_cpp"]
