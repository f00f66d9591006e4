"""The binding driver's memory of original values, with fake nodes (no ROS graph): an
original is forgotten only once the switch that restores it succeeded, so a failed or
rolled-back restore finds it again next time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from rcl_interfaces.msg import ParameterType

from contextros.bindings import Bindings
from contextros.ros.bindings import (
    BindingDriver,
    BindingError,
    CallTimedOut,
    shown,
    to_parameter_value,
)

LAYERS = """\
parameter Slow: /base max_speed = 0.3
lifecycle Outdoor: /propeller active
lifecycle Indoor: /propeller inactive
"""
_STATES = {1: ("unconfigured", "inactive"), 2: ("inactive", "unconfigured")}
_STATES |= {3: ("inactive", "active"), 4: ("active", "inactive")}


class _Logger:
    def __init__(self) -> None:
        self.errors: list[str] = []

    def error(self, text: str) -> None:
        self.errors.append(text)

    def warning(self, text: str) -> None:
        self.errors.append(text)


class _Node:
    def __init__(self) -> None:
        self.logger = _Logger()

    def get_namespace(self) -> str:
        return "/"

    def get_logger(self) -> _Logger:
        return self.logger

    def create_client(self, service_type: Any, name: str) -> object:
        return object()


class FakeDriver(BindingDriver):
    """Nodes held in dictionaries; `down` nodes do not answer, `rejecting` nodes refuse
    every parameter value, `refused` transitions fail; `late` nodes carry a change out but
    answer too late; `crash` is raised by a transition once it is done (the manager dies)."""

    def __init__(self, bindings: Bindings, memory: Path | None = None) -> None:
        super().__init__(_Node(), bindings, memory=memory)  # type: ignore[arg-type]
        self.parameters: dict[tuple[str, str], Any] = {
            ("/base", "max_speed"): to_parameter_value(1.0)
        }
        self.states = {"/propeller": "unconfigured"}
        self.down: set[str] = set()
        self.rejecting: set[str] = set()
        self.refused: set[str] = set()
        self.late: set[str] = set()
        self.crash: BaseException | None = None

    def _answering(self, node: str) -> None:
        if node in self.down:
            raise BindingError(f"node {node} does not answer")

    def _get(self, node: str, name: str) -> Any:
        self._answering(node)
        return self.parameters[(node, name)]

    def _set(self, node: str, name: str, value: Any, layer: str = "") -> None:
        self._answering(node)
        if node in self.rejecting:
            raise BindingError(f"node {node} rejected parameter {name} = {shown(value)}")
        self.parameters[(node, name)] = value
        if node in self.late:
            self.late.discard(node)
            raise CallTimedOut(f"node {node} did not answer setting parameter {name}")

    def _get_state(self, node: str) -> str:
        self._answering(node)
        return self.states[node]

    def _change_state(
        self, node: str, transition_id: int, label: str, layer: str = "", current: str = ""
    ) -> None:
        self._answering(node)
        if label in self.refused:
            raise BindingError(f"lifecycle node {node}: transition {label} failed")
        before, after = _STATES[transition_id]
        assert self.states[node] == before
        self.states[node] = after
        if self.crash is not None:
            raise self.crash

    def speed(self) -> str:
        return shown(self.parameters[("/base", "max_speed")])


def bindings(tmp_path: Path) -> Bindings:
    path = tmp_path / "robot.layers"
    path.write_text(LAYERS, encoding="utf-8")
    return Bindings.from_files([path])


@pytest.fixture
def driver(tmp_path: Path) -> FakeDriver:
    return FakeDriver(bindings(tmp_path))


def test_a_failed_restore_keeps_the_original_for_the_next_try(driver: FakeDriver) -> None:
    driver.switch((), ("Slow",))
    assert driver.speed() == "0.3"
    driver.rejecting.add("/base")
    with pytest.raises(BindingError):
        driver.switch(("Slow",), ())
    assert driver.applied == ("Slow",) and driver.speed() == "0.3"
    driver.rejecting.clear()
    driver.switch(("Slow",), ())
    assert driver.speed() == "1", "the value from before Slow, not Slow's"


def test_a_restore_rolled_back_by_a_later_step_keeps_the_original(driver: FakeDriver) -> None:
    driver.switch((), ("Indoor", "Slow"))
    assert (driver.speed(), driver.states["/propeller"]) == ("0.3", "inactive")
    driver.refused.add("activate")
    with pytest.raises(BindingError):  # max_speed restored, then rolled back
        driver.switch(("Indoor", "Slow"), ("Outdoor",))
    assert (driver.speed(), driver.states["/propeller"]) == ("0.3", "inactive")
    driver.refused.clear()
    driver.switch(("Indoor", "Slow"), ("Indoor",))
    assert driver.speed() == "1"
    driver.switch(("Indoor",), ())
    assert driver.states["/propeller"] == "unconfigured"


def test_a_failed_lifecycle_restore_keeps_the_original_state(driver: FakeDriver) -> None:
    driver.switch((), ("Outdoor",))
    assert driver.states["/propeller"] == "active"
    driver.refused.add("cleanup")
    with pytest.raises(BindingError):
        driver.switch(("Outdoor",), ())
    assert driver.states["/propeller"] == "active", "deactivate rolled back"
    driver.refused.clear()
    driver.switch(("Outdoor",), ())
    assert driver.states["/propeller"] == "unconfigured"


def test_a_rolled_back_first_switch_reads_the_original_again(driver: FakeDriver) -> None:
    driver.refused.add("activate")
    with pytest.raises(BindingError):
        driver.switch((), ("Outdoor", "Slow"))
    assert driver.speed() == "1"
    driver.refused.clear()
    driver.parameters[("/base", "max_speed")] = to_parameter_value(2.0)  # changed by hand
    driver.switch((), ("Slow",))
    driver.switch(("Slow",), ())
    assert driver.speed() == "2"


def test_a_node_down_changes_nothing_and_is_tried_again(driver: FakeDriver) -> None:
    driver.switch((), ("Slow",))
    driver.down.add("/base")
    with pytest.raises(BindingError):
        driver.switch(("Slow",), ())
    driver.down.clear()
    driver.switch(("Slow",), ())
    assert driver.speed() == "1"


def test_a_parameter_without_a_value_before_keeps_the_layers(driver: FakeDriver) -> None:
    driver.parameters[("/base", "max_speed")] = to_parameter_value(None)
    driver.switch((), ("Slow",))
    driver.switch(("Slow",), ())
    assert driver.speed() == "0.3"
    assert driver.parameters[("/base", "max_speed")].type == ParameterType.PARAMETER_DOUBLE


def restarted(before: FakeDriver, tmp_path: Path) -> FakeDriver:
    """A new driver (a restarted manager) on the same nodes and memory file."""
    after = FakeDriver(bindings(tmp_path), before.memory)
    after.parameters, after.states = before.parameters, before.states
    return after


def test_a_restarted_manager_still_restores_the_values_from_before(tmp_path: Path) -> None:
    memory = tmp_path / "state.json.bindings.json"
    first = FakeDriver(bindings(tmp_path), memory)
    first.switch((), ("Slow", "Outdoor"))
    assert (first.speed(), first.states["/propeller"]) == ("0.3", "active")
    second = restarted(first, tmp_path)
    assert second.applied == ("Slow", "Outdoor")
    second.switch(second.applied, ())
    assert (second.speed(), second.states["/propeller"]) == ("1", "unconfigured")
    assert restarted(second, tmp_path).applied == ()
    assert '"parameters": []' in memory.read_text(encoding="utf-8"), "all forgotten"


def test_kept_values_keep_their_types(tmp_path: Path) -> None:
    memory = tmp_path / "memory.json"
    first = FakeDriver(bindings(tmp_path), memory)
    for value in (True, 7, 2.0, "eco"):
        first.parameters[("/base", "max_speed")] = to_parameter_value(value)
        first.kept.parameters.clear()
        first.switch((), ("Slow",))
        second = restarted(first, tmp_path)
        second.switch(("Slow",), ())
        assert second.parameters[("/base", "max_speed")] == to_parameter_value(value)
        first.settled(())


def test_a_damaged_memory_is_logged_and_ignored(tmp_path: Path) -> None:
    memory = tmp_path / "memory.json"
    for text in (
        "{",
        '{"applied": [1], "parameters": [], "lifecycles": {}}',
        '{"applied": [], "parameters": [{"node": "/base", "name": "x", "type": 3, '
        '"value": "no"}], "lifecycles": {}}',
    ):
        memory.write_text(text, encoding="utf-8")
        driver = FakeDriver(bindings(tmp_path), memory)
        assert driver.applied == () and not driver.kept.parameters
        assert "ignored" in driver.node.get_logger().errors[0]  # type: ignore[attr-defined]


def test_a_set_answered_too_late_is_read_back_and_undone(driver: FakeDriver) -> None:
    driver.late.add("/base")
    with pytest.raises(BindingError) as refused:
        driver.switch((), ("Slow",))
    assert str(refused.value) == (
        "node /base did not answer setting parameter max_speed, so whether it did is unknown: "
        "/base had max_speed = 0.3: set back to 1; everything the command changed is undone, "
        "no state published"
    )
    assert driver.speed() == "1" and driver.applied == () and not driver.unsettled


class _Killed(BaseException):
    """The manager's process ends here (kill -9): nothing after it runs."""


def test_what_to_give_back_is_on_disk_before_anything_changes(tmp_path: Path) -> None:
    memory = tmp_path / "state.json.bindings.json"
    first = FakeDriver(bindings(tmp_path), memory)
    first.crash = _Killed()
    with pytest.raises(_Killed):  # max_speed set, the propeller configured, then killed
        first.switch((), ("Slow", "Outdoor"))
    assert (first.speed(), first.states["/propeller"]) == ("0.3", "inactive")
    second = restarted(first, tmp_path)
    second.crash = None
    assert second.applied == () and second.unsettled
    second.switch(second.applied, ())  # the recovered state: what the manager reconciles to
    assert (second.speed(), second.states["/propeller"]) == ("1", "unconfigured")
    assert not second.unsettled and not second.kept.parameters and not second.kept.states
