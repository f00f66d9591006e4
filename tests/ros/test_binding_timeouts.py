"""Slow nodes and a manager killed mid-switch, on real processes: a lifecycle node that takes
seconds to activate (`plain_nodes_process.py --slow-activate`), `manager --binding-timeout`,
and the bindings file written before anything changes on ROS."""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from lifecycle_msgs.srv import GetState
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node

from contextros.ros import LayerClient, ManagerError
from tests.ros.processes import HERE, Child, ProcessGroup
from tests.ros.system import LIVENESS, wait_registry
from tests.ros.test_ros_bindings import call

LAYERS = """\
parameter Flight: base max_speed = 0.9
lifecycle Flight: propeller active
"""
SLOW_ACTIVATE = 2.5  # seconds the propeller's on_activate takes (the old fixed limit: 2 s)


@contextmanager
def robot(
    processes: ProcessGroup, tmp_path: Path, namespace: str, *manager: str
) -> Iterator[tuple[LayerClient, Child, Child]]:
    """Plain nodes with a slow propeller, a participant and a manager in `namespace`: a
    client there, the plain nodes' process and the manager's."""
    layers = tmp_path / "robot.layers"
    layers.write_text(LAYERS, encoding="utf-8")
    ros = ("--ros-args", "-r", f"__ns:={namespace}")
    plain = processes.start(
        f"{namespace} plain nodes",
        [str(HERE / "plain_nodes_process.py"), "--slow-activate", str(SLOW_ACTIVATE), *ros],
    )
    processes.participant(f"{namespace.strip('/')}_p", *ros)
    started = processes.manager(
        "--liveness-timeout", LIVENESS, "--layers", str(layers), *manager, *ros, name=namespace
    )
    plain.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    node = Node(f"{namespace.strip('/')}_client", namespace=namespace)
    try:
        client = LayerClient(node, "pytest")
        client.wait_for_manager(15.0)
        wait_registry(client, lambda r: not r.recovering and len(r.participants) == 1)
        yield client, plain, started
    finally:
        node.destroy_node()


def speed(client: LayerClient) -> float:
    name = f"{client.node.get_namespace()}/base/get_parameters"
    response = call(client, GetParameters, name, GetParameters.Request(names=["max_speed"]))
    return float(response.values[0].double_value)


def propeller(client: LayerClient) -> str:
    name = f"{client.node.get_namespace()}/propeller/get_state"
    return str(call(client, GetState, name, GetState.Request()).current_state.label)


def eventually(what: str, check: Callable[[], bool], timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, what
        time.sleep(0.2)


def test_a_slow_activation_succeeds_within_the_binding_timeout_and_the_commands(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    """With --binding-timeout 5 an activation of 2.5 s succeeds; within a command whose
    caller gives up sooner (timeout 0.1 s + 2 s), the call is cut there and rolled back."""
    with robot(processes, tmp_path, "/patient", "--binding-timeout", "5") as (patient, _, m):
        result = patient.request(["Flight"], synchronous=True, timeout=10)
        assert result.success, result.message
        assert result.elapsed > SLOW_ACTIVATE
        assert (propeller(patient), speed(patient)) == ("active", pytest.approx(0.9))
        assert list(patient.query().active_layers) == ["Flight"]
        assert patient.request([], ["Flight"], synchronous=True, timeout=10).success
        with pytest.raises(ManagerError, match="whether the command was carried out is unknown"):
            patient.request(["Flight"], synchronous=True, timeout=0.1)
        eventually("the propeller brought back", lambda: propeller(patient) == "unconfigured")
        assert "Flight" not in patient.query().active_layers and speed(patient) == 1.0
        eventually(
            "the manager's log says why",
            lambda: (
                "what was left of the command's timeout of 0.1 s + 2 s), so whether it "
                "did is unknown: lifecycle node /patient/propeller was active: brought back to "
                "unconfigured" in m.output()
            ),
        )


def test_a_call_that_times_out_is_reported_and_its_node_brought_back(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    """The activation outlasts the 1 s binding timeout: its outcome is unknown, so the node
    is read afterwards (it did activate), brought back, and the message says so."""
    with robot(processes, tmp_path, "/hasty", "--binding-timeout", "1") as (hasty, _, _):
        before = hasty.query()
        result = hasty.request(["Flight"], synchronous=True, timeout=10)
        assert not result.success
        assert result.message == (
            "node /hasty/propeller did not answer transition activate within 1 s, so whether "
            "it did is unknown: lifecycle node /hasty/propeller was active: brought back to "
            "unconfigured (deactivate, cleanup); everything the command changed is undone, "
            "no state published"
        )
        after = hasty.query()
        assert (after.epoch, list(after.active_layers)) == (before.epoch, [])
        assert (propeller(hasty), speed(hasty)) == ("unconfigured", 1.0)


def test_a_manager_killed_mid_switch_gives_the_nodes_back_their_own_values(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    """kill -9 while the propeller activates (max_speed already set): what to give back was
    on disk before the first change, so the restarted manager restores 1.0 and
    unconfigured, and a later Flight on and off does too."""
    state_file = tmp_path / "state.json"
    arguments = ("--state-file", str(state_file))
    with robot(processes, tmp_path, "/killed", *arguments) as (killed, plain, manager):
        killed.request_async(["Flight"], synchronous=True, timeout=10)
        plain.wait_for(lambda events: any(e["event"] == "activating" for e in events), 10, "act")
        manager.signal(signal.SIGKILL)
        manager.wait_exit()
        assert speed(killed) == pytest.approx(0.9)
        kept = json.loads(state_file.with_name("state.json.bindings.json").read_text("utf-8"))
        assert kept["unsettled"] == [["Flight"]]
        assert kept["lifecycles"] == {"/killed/propeller": "unconfigured"}
        [original] = kept["parameters"]
        assert (original["name"], original["value"]) == ("max_speed", 1.0)
        ros = ("--ros-args", "-r", "__ns:=/killed")
        processes.manager("--layers", str(tmp_path / "robot.layers"), *arguments, *ros)
        eventually("max_speed given back", lambda: speed(killed) == 1.0)
        eventually("propeller given back", lambda: propeller(killed) == "unconfigured")
        registry = wait_registry(killed, lambda r: not r.recovering)
        assert list(registry.active_layers) == []
        # The originals are still the node's own: a switch there and back ends on them.
        assert killed.request(["Flight"], synchronous=True, timeout=10).success
        assert killed.request([], ["Flight"], synchronous=True, timeout=10).success
        assert (propeller(killed), speed(killed)) == ("unconfigured", 1.0)


def test_a_manager_stopped_mid_switch_says_what_it_leaves_and_answers(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    """SIGTERM while the propeller activates: the manager exits 0 as documented (it exited 1
    with a traceback when the signal came during a take), but first logs what the nodes
    keep, and answers the waiting command if a reply can still go out."""
    answers: list[object] = []
    with robot(processes, tmp_path, "/stopping") as (near, plain, manager):

        def ask() -> None:
            try:
                answers.append(near.request(["Flight"], synchronous=True, timeout=10).message)
            except ManagerError as error:
                answers.append(str(error))

        asking = threading.Thread(target=ask, daemon=True)
        asking.start()
        plain.wait_for(lambda events: any(e["event"] == "activating" for e in events), 10)
        manager.signal(signal.SIGTERM)
        status = manager.wait_exit(10)
        assert status == 0, f"exit status {status}: {manager.output()}"
        asking.join(15)
    said = manager.output()
    assert "stopped while setting the parameters and lifecycle states of [Flight]" in said, said
    assert "nothing gives them back (no --state-file)" in said, said
    # Answered when the context still lets a reply out (a signal may have shut it first).
    assert answers and any(
        words in str(answers[0]) for words in ("stopped while setting", "is unknown")
    ), answers
