"""Two robots in one ROS domain: a manager and two context nodes each, in /robot1 and
/robot2, switched independently (every protocol name is relative to the node namespace)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from rclpy.node import Node

from contextros.ros import LayerClient
from tests.ros.processes import PARTICIPANT_SCRIPT, Child, ProcessGroup
from tests.ros.system import LIVENESS, wait_for_manager, wait_registry
from tests.ros.test_cli import contextros

ROBOTS = ("/robot1", "/robot2")


@dataclass
class Robot:
    namespace: str
    manager: Child
    nodes: dict[str, Child]
    client: LayerClient


@pytest.fixture(scope="module")
def robots(client: LayerClient) -> Iterator[dict[str, Robot]]:
    group = ProcessGroup()
    clients: list[Node] = []
    try:
        robots: dict[str, Robot] = {}
        for namespace in ROBOTS:
            remap = ("--ros-args", "-r", f"__ns:={namespace}")
            nodes = {
                name: group.start(
                    f"{namespace}/{name}",
                    [str(PARTICIPANT_SCRIPT), "--name", name, *remap],
                )
                for name in ("p1", "p2")
            }
            manager = group.manager(
                "--liveness-timeout", LIVENESS, *remap, name=f"{namespace} manager"
            )
            node = Node("namespace_test_client", namespace=namespace)
            clients.append(node)
            robots[namespace] = Robot(namespace, manager, nodes, LayerClient(node, "pytest"))
        for robot in robots.values():
            wait_for_manager(robot.client, robot.manager)
            wanted = {f"{robot.namespace}/p1", f"{robot.namespace}/p2"}
            wait_registry(
                robot.client,
                lambda r, wanted=wanted: (
                    r.epoch >= 1 and {p.node for p in r.participants} >= wanted
                ),
                what=f"{sorted(wanted)} registered",
            )
        yield robots
    finally:
        group.kill_all()
        for node in clients:
            node.destroy_node()


def test_each_manager_knows_only_its_own_robots_nodes(robots: dict[str, Robot]) -> None:
    for namespace, robot in robots.items():
        registry = robot.client.query()
        assert sorted(p.node for p in registry.participants) == [
            f"{namespace}/p1",
            f"{namespace}/p2",
        ]


def test_two_robots_switch_independently(robots: dict[str, Robot]) -> None:
    one, two = robots["/robot1"], robots["/robot2"]
    first = one.client.request(["Indoor"], synchronous=True, timeout=5)
    assert first.success, first.message
    assert first.acknowledged == ("/robot1/p1", "/robot1/p2")
    second = two.client.request(["Outdoor", "Night"], synchronous=True, timeout=5)
    assert second.success, second.message
    assert second.acknowledged == ("/robot2/p1", "/robot2/p2")
    for child in one.nodes.values():
        assert child.wait_applied(first.epoch)["mode"] == "wipe+base"
    for child in two.nodes.values():
        assert child.wait_applied(second.epoch)["mode"] == "quiet+vacuum+base"
    # No cross-talk: robot1's nodes never applied a state with robot2's layers, and back.
    assert all("Outdoor" not in e["active"] for c in one.nodes.values() for e in c.applied())
    assert all("Indoor" not in e["active"] for c in two.nodes.values() for e in c.applied())
    assert list(one.client.query().active_layers) == ["Indoor"]
    assert list(two.client.query().active_layers) == ["Outdoor", "Night"]


def test_the_command_line_takes_the_namespace(robots: dict[str, Robot]) -> None:
    # This test may run in another pytest-xdist worker than the previous one (a fixture of
    # its own): set robot2's layers here rather than rely on it.
    settled = robots["/robot2"].client.request(["Outdoor", "Night"], synchronous=True, timeout=5)
    assert settled.success, settled.message
    done = contextros(
        "switch", "--on", "Outdoor", "--off", "Indoor", "--sync", "--json", "--namespace", "/robot1"
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["acknowledged"] == ["/robot1/p1", "/robot1/p2"]
    shown = contextros("status", "--json", "--ros-args", "-r", "__ns:=/robot2")
    assert shown.returncode == 0, shown.stderr
    status = json.loads(shown.stdout)
    assert {p["node"] for p in status["participants"]} == {"/robot2/p1", "/robot2/p2"}
    assert status["active"] == ["Outdoor", "Night"]
    assert list(robots["/robot1"].client.query().active_layers) == ["Outdoor"]


def test_no_manager_in_a_namespace_is_named_in_the_error() -> None:
    missing = contextros("status", "--namespace", "/robot9", "--wait-manager", "0.5")
    assert missing.returncode == 3
    assert "no Layer manager answers on /robot9/contextros/query " in missing.stderr  # status's


@pytest.mark.parametrize(
    "argv",
    [
        ["status", "--namespace", "robot 1"],
        ["manager", "--namespace", "/9robot"],
        ["status", "--ros-args", "-r", "no-separator"],
    ],
)
def test_bad_namespaces_and_ros_arguments_are_usage_errors(argv: list[str]) -> None:
    refused = contextros(*argv)
    assert refused.returncode == 2, refused.stderr
    assert "contextros:" in refused.stderr
    assert "Traceback" not in refused.stderr
