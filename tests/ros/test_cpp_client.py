"""The C++ activation client (cpp/ros/src/client.cpp) against the real Layer manager: it
switches a Python and a C++ node, and answers as the Python client does (epoch,
acknowledged, not acknowledged, the manager's reason) for asynchronous, synchronous and
atomic commands, expectations, refusals, invalid commands and a missing manager; against a
late stand-in manager, a short timeout waited for and a late first answer taken; Ctrl-C
ending a command that waits for its answer.

The client runs in cpp/ros/tests/client_process.cpp: a command per line on stdin, a JSON
answer per line on stdout.
"""

from __future__ import annotations

import signal
import time
from typing import Any

from contextros.ros import LayerClient
from contextros.ros.client import REPLY_MARGIN, RESEND_AFTER
from tests.ros.processes import HERE, Child, ProcessGroup
from tests.ros.system import LIVENESS, start_system, wait_for_manager, wait_registry
from tests.ros.test_client_resend import LATE, SHORT, arrivals, late_manager

CPP_CLIENT = HERE.parent.parent / "build/cpp/ros/contextros_test_client"


def cpp_client(processes: ProcessGroup, name: str = "cpp_client") -> Child:
    if not CPP_CLIENT.exists():
        raise AssertionError(f"{CPP_CLIENT} is not built: run `make cpp`")
    child = Child(name, ["--name", name, "--requester", "cxx-tests"], program=str(CPP_CLIENT))
    processes.children.append(child)
    child.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15, "ready")
    return child


def ask(child: Child, line: str, timeout: float = 15.0) -> dict[str, Any]:
    """Send one command; its answer (or error) event."""
    seen = len([e for e in child.events if e["event"] in ("answer", "error", "manager")])
    child.send(line)
    return child.wait_for(
        lambda events: next(
            iter([e for e in events if e["event"] in ("answer", "error", "manager")][seen:]),
            None,
        ),
        timeout,
        line,
    )


def both_on_the_current_state(registry: Any) -> bool:
    return len(registry.participants) == 2 and all(
        p.applied_epoch == registry.epoch for p in registry.participants
    )


def test_the_cpp_client_switches_a_python_and_a_cpp_node(
    client: LayerClient, processes: ProcessGroup
) -> None:
    cpp_node = processes.cpp_participant("cxx")
    system = start_system(processes, client, ["py"])
    wait_registry(
        client,
        both_on_the_current_state,
        what="both participants",
        show=[cpp_node, system.manager],
    )
    cxx_client = cpp_client(processes)
    assert ask(cxx_client, "wait 15")["event"] == "manager"

    synchronous = ask(cxx_client, "activate on=Indoor sync timeout=5 reason=inside")
    assert synchronous["event"] == "answer" and synchronous["success"], synchronous
    assert synchronous["acknowledged"] == ["/cxx", "/py"]
    assert synchronous["not_acknowledged"] == [] and synchronous["active"] == ["Indoor"]
    registry = client.query()
    assert (registry.epoch, registry.requester, registry.reason) == (
        synchronous["epoch"],
        "cxx-tests",
        "inside",
    ), "the request carries the C++ client's requester and reason"

    switched = ask(cxx_client, "switch off=Indoor on=Outdoor,Night sync timeout=5")
    assert switched["success"], switched
    assert switched["active"] == ["Outdoor", "Night"]
    assert switched["epoch"] == synchronous["epoch"] + 1
    for node in (cpp_node, system.participants["py"]):
        applied = node.wait_applied(switched["epoch"], timeout=2)
        assert applied["active"] == ["Outdoor", "Night"], node.name
        assert applied["mode"] == "quiet+vacuum+base", node.name

    # The default, asynchronous: answered once published, no acknowledgements asked for.
    published = ask(cxx_client, "deactivate off=Night")
    assert published["success"] and published["acknowledged"] == [], published
    assert published["active"] == ["Outdoor"]
    for node in (cpp_node, system.participants["py"]):
        assert node.wait_applied(published["epoch"], timeout=5)["active"] == ["Outdoor"]
    # request_async (a future) answers the same way.
    unchanged = ask(cxx_client, "async on=Outdoor")
    assert unchanged["success"] and unchanged["message"] == "no change", unchanged
    assert unchanged["epoch"] == published["epoch"]


def test_the_cpp_client_reports_vetoes_refusals_and_expectations(
    client: LayerClient, processes: ProcessGroup
) -> None:
    cpp_node = processes.cpp_participant("cxx")
    system = start_system(processes, client, ["voter"], "--default-timeout", "5")
    wait_registry(
        client,
        both_on_the_current_state,
        what="both participants",
        show=[cpp_node, system.manager],
    )
    before = client.query().epoch
    cxx_client = cpp_client(processes)
    ask(cxx_client, "wait 15")

    committed = ask(cxx_client, "request on=Indoor atomic timeout=5")
    assert committed["success"], committed
    assert committed["acknowledged"] == ["/cxx", "/voter"]

    refused = ask(cxx_client, "request on=Slow,Fast sync timeout=5")
    assert not refused["success"] and "Slow excludes Fast" in refused["message"], refused
    assert refused["epoch"] == committed["epoch"], "a refusal changes nothing"
    failed = ask(cxx_client, "activate on=Slow,Fast")
    assert failed["event"] == "error" and failed["kind"] == "ActivationFailed", failed
    assert "Slow excludes Fast" in failed["message"]

    expecting = ask(cxx_client, "request on=Night sync timeout=1 expect=/cxx,/ghost")
    assert not expecting["success"], expecting
    assert expecting["not_acknowledged"] == ["/ghost"], expecting
    assert "/ghost" in expecting["message"]
    counted = ask(cxx_client, "request off=Night sync timeout=1 count=3")
    assert not counted["success"] and "3" in counted["message"], counted

    invalid = ask(cxx_client, "request on=Night timeout=-1")
    assert invalid["kind"] == "ActivationFailed", invalid
    assert invalid["message"] == "invalid command: timeout -1 s is outside 0..3600 s; nothing sent"
    assert client.query().epoch > before


def test_an_atomic_command_vetoed_by_a_python_node_changes_no_node(
    client: LayerClient, processes: ProcessGroup
) -> None:
    cpp_node = processes.cpp_participant("cxx")
    processes.participant("vetoer", "--veto", "docking")
    manager = processes.manager("--liveness-timeout", LIVENESS)
    wait_for_manager(client, manager)
    wait_registry(
        client,
        both_on_the_current_state,
        what="the C++ node and the vetoer",
        show=[cpp_node, manager],
    )
    cxx_client = cpp_client(processes)
    ask(cxx_client, "wait 15")
    started = time.monotonic()
    vetoed = ask(cxx_client, "switch on=Outdoor atomic timeout=5")
    assert time.monotonic() - started < 3.0, "a veto is answered at once"
    assert vetoed["kind"] == "ActivationFailed", vetoed
    assert "/vetoer vetoed: docking" in vetoed["message"], vetoed
    assert vetoed["not_acknowledged"] == ["/vetoer"]
    # Nothing changed anywhere: no node applied Outdoor (the manager's own first state, with
    # no layer, may come after `epoch` was read on a loaded machine).
    assert "Outdoor" not in client.query().active_layers
    assert all("Outdoor" not in a.get("active", ()) for a in cpp_node.applied()), cpp_node.applied()


def test_without_a_manager_the_cpp_client_says_so_within_its_timeout(
    processes: ProcessGroup,
) -> None:
    cxx_client = cpp_client(processes, "lonely_client")
    started = time.monotonic()
    missing = ask(cxx_client, "wait 0.5")
    assert missing["kind"] == "ManagerError", missing
    assert missing["message"].startswith("no Layer manager answers on /contextros/activate")
    assert "after 0.5 s" in missing["message"]
    unanswered = ask(cxx_client, "request on=Night sync timeout=0.5")
    elapsed = time.monotonic() - started
    assert unanswered["kind"] == "ManagerError", unanswered
    assert "whether the command was carried out is unknown" in unanswered["message"]
    assert 2.5 <= elapsed < 5.0, f"gives up 2 s after the timeout, not {elapsed:.1f} s"


def test_against_a_late_manager_the_cpp_client_waits_and_takes_any_attempts_answer(
    processes: ProcessGroup,
) -> None:
    """As the Python client (test_client_resend.py): a SHORT timeout leaves no time for a
    resend, so the command sent is waited for until the client gives up (it gave up at
    RESEND_AFTER); without a timeout, the first attempt's answer, coming after the resend,
    is taken (it was dropped, and the third attempt's waited for)."""
    with late_manager() as arrived:
        cxx_client = cpp_client(processes, "late_client")
        assert ask(cxx_client, "wait 15")["event"] == "manager"
        started = time.monotonic()
        short = ask(cxx_client, f"request on=Night timeout={SHORT}")
        assert short["event"] == "answer" and short["message"] == "answer 1", short
        assert LATE <= time.monotonic() - started < SHORT + REPLY_MARGIN
        assert len(arrived) == 1, "not sent again"

        started = time.monotonic()
        resent = ask(cxx_client, "request on=Night")
        assert resent["event"] == "answer" and resent["message"] == "answer 2", resent
        assert LATE <= time.monotonic() - started < RESEND_AFTER + LATE
        assert arrivals(arrived, 3) == 3, "sent again once"


def test_ctrl_c_ends_a_cpp_command_waiting_for_its_answer(processes: ProcessGroup) -> None:
    """The program's SIGINT shuts the ROS context down (as rclcpp's handler does): a command
    no manager answers ends within the client's 100 ms look at the context, with
    ManagerError, not at its deadline (32 s here)."""
    cxx_client = cpp_client(processes, "interrupted_client")
    cxx_client.send("request on=Night sync timeout=30")
    time.sleep(1.0)  # waiting for its answer
    interrupted = time.monotonic()
    cxx_client.signal(signal.SIGINT)
    ended = cxx_client.wait_for(
        lambda events: any(e["event"] == "shutdown" for e in events) and events, 5.0, "shutdown"
    )
    assert time.monotonic() - interrupted < 2.0
    error = next(e for e in ended if e["event"] == "error")
    assert error["kind"] == "ManagerError", error
    assert error["message"].startswith("ROS was shut down before the Layer manager answered")
    assert "whether the command was carried out is unknown" in error["message"]
    assert cxx_client.wait_exit(5.0) == 0
