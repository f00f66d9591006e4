"""Where a C++ node belongs: its process (the nodes of one process share one participant;
when its carrier goes, the next node of the process takes it over, as the Python
ContextNode does: test_shared_participant.py) and its namespace (it follows that
namespace's manager only)."""

from __future__ import annotations

import time

from contextros.ros import LayerClient
from tests.ros.processes import ProcessGroup
from tests.ros.system import start_system, wait_registry


def test_the_next_cpp_node_takes_the_shared_participant_over(
    client: LayerClient, processes: ProcessGroup
) -> None:
    both = processes.cpp_participant("carrier_cxx", "--also", "guest_cxx")
    both.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    system = start_system(processes, client, ["py_peer"])
    registry = wait_registry(
        client,
        lambda r: any(list(p.hosted_nodes) == ["/guest_cxx"] for p in r.participants),
        what="/carrier_cxx registered, hosting /guest_cxx",
    )
    assert sorted(p.node for p in registry.participants) == ["/carrier_cxx", "/py_peer"]
    first = client.request(["Night"], synchronous=True, timeout=5)
    assert first.success, first.message
    assert first.acknowledged == ("/carrier_cxx", "/guest_cxx", "/py_peer")

    both.send("drop-first")
    dropped = both.wait_for(
        lambda events: next((e for e in events if e["event"] == "dropped-first"), None), 10
    )
    assert dropped["carrier"] == "/guest_cxx"
    # The carrier said it leaves; the guest now speaks for itself, as a new incarnation.
    deadline = time.monotonic() + 10
    while not any("/carrier_cxx dropped: left" in line for line in system.manager.lines):
        assert time.monotonic() < deadline, system.manager.output()
        time.sleep(0.05)
    wait_registry(
        client,
        lambda r: sorted(p.node for p in r.participants) == ["/guest_cxx", "/py_peer"],
        what="/guest_cxx carrying the participant",
    )
    second = client.request(["Outdoor"], synchronous=True, timeout=5)
    assert second.success, second.message
    assert second.acknowledged == ("/guest_cxx", "/py_peer")
    # The process's state listener was carried over to the new participant.
    applied = both.wait_applied(second.epoch)
    assert applied["active"] == ["Night", "Outdoor"]
    assert applied["mode"] == "vacuum+quiet+base"
    # The new participant carried on from the process's epoch: the manager's current state
    # (transient local) was nothing new to it, so it applied only the later one.
    after = both.events[both.events.index(dropped) :]
    assert [e["epoch"] for e in after if e["event"] == "applied"] == [second.epoch]


def test_a_cpp_node_follows_the_manager_of_its_namespace(
    client: LayerClient, processes: ProcessGroup
) -> None:
    """Protocol names are relative: a C++ node in /cxx_robot follows /cxx_robot's manager."""
    from rclpy.node import Node

    remap = ("--ros-args", "-r", "__ns:=/cxx_robot")
    inside = processes.cpp_participant("arm", *remap)
    outside = processes.cpp_participant("arm")  # same name, default namespace: another system
    processes.manager("--liveness-timeout", "1.0", *remap, name="namespaced manager")
    node = Node("cpp_namespace_test_client", namespace="/cxx_robot")
    try:
        robot = LayerClient(node, "pytest")
        robot.wait_for_manager(15.0)
        wait_registry(
            robot,
            lambda r: r.epoch >= 1 and [p.node for p in r.participants] == ["/cxx_robot/arm"],
            what="/cxx_robot/arm registered with its namespace's manager",
        )
        result = robot.request(["Outdoor"], synchronous=True, timeout=5)
        assert result.success and result.acknowledged == ("/cxx_robot/arm",), result.message
        assert inside.wait_applied(result.epoch)["mode"] == "vacuum+base"
        time.sleep(0.3)
        assert outside.applied() == [], "the default namespace has no manager: nothing applied"
    finally:
        node.destroy_node()
