"""Two component libraries loaded into one process with dlopen(), as a component container
loads its components: because libcontextros_core and libcontextros_ros are shared
libraries, they share the process's one runtime and one participant (built by `make cpp`:
cpp/ros/tests/components/)."""

from __future__ import annotations

from contextros.ros import LayerClient
from tests.cpp.conftest import CPP_BUILD
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import wait_registry

HOST = CPP_BUILD / "ros" / "contextros_test_components_host"
COMPONENTS = [
    CPP_BUILD / "ros" / f"libcontextros_test_component_{name}.so" for name in ("wheels", "lights")
]


def _line(child: Child, text: str) -> str:
    return child.wait_for(
        lambda _: next((line for line in child.lines if text in line), None), 10, repr(text)
    )


def test_two_dlopened_components_share_one_runtime_and_one_participant(
    client: LayerClient, processes: ProcessGroup
) -> None:
    assert HOST.exists(), f"{HOST} is not built: run `make cpp`"
    processes.manager()
    host = Child("components host", [str(path) for path in COMPONENTS], program=str(HOST))
    processes.children.append(host)
    _line(host, "ready")
    # The second component found the first one's participant: it is hosted, not a second one.
    assert "lights started, carrier /wheels" in host.output()
    registry = wait_registry(
        client,
        lambda r: (
            [(p.node, list(p.hosted_nodes)) for p in r.participants] == [("/wheels", ["/lights"])]
        ),
        what="one participant, /wheels, hosting /lights",
    )
    # One runtime: both libraries define the layers Fast and Slow; each appears once.
    assert sorted(layer.name for layer in registry.layers) == ["Fast", "Slow"]

    result = client.request(["Fast"], synchronous=True, timeout=5)
    assert result.success, result.message
    assert result.acknowledged == ("/lights", "/wheels")
    # One decisive switch of the one runtime rewired the layered functions of both.
    assert _line(host, f"wheels epoch {result.epoch} ").endswith(": full speed")
    assert _line(host, f"lights epoch {result.epoch} ").endswith(": blinking")
