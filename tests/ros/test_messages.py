"""The adapter's translation between rosidl messages and protocol values loses nothing."""

from __future__ import annotations

from contextros.protocol import (
    ActivationResult,
    LayerDeclaration,
    LayerState,
    ParticipantReport,
)
from contextros.ros.messages import (
    command_from_request,
    command_to_request,
    fill_response,
    report_from_msg,
    report_to_msg,
    result_from_response,
    state_from_msg,
    state_to_msg,
)


def test_state_round_trip() -> None:
    state = LayerState(7, ("Outdoor", "Gps"), "cli", "went out", stamp=0.0, manager_id="m1")
    back = state_from_msg(state_to_msg(state, wall_time=1700000000.25))
    assert (back.epoch, back.active, back.requester, back.reason) == (
        7,
        ("Outdoor", "Gps"),
        "cli",
        "went out",
    )
    assert (back.manager_id, back.stamp) == ("m1", 1700000000.25)


def test_report_round_trip() -> None:
    report = ParticipantReport(
        node="/cleaner",
        incarnation="42-abc",
        layers=(
            LayerDeclaration("Gps", requires=frozenset({"Outdoor"})),
            LayerDeclaration("Slow", excludes=frozenset({"Fast", "Turbo"}), group="speed"),
        ),
        applied_epoch=5,
        active=("Outdoor", "Gps"),
        applied_manager_id="m1",
        in_critical_section=True,
        pending_epoch=6,
        failed_epoch=4,
        error="epoch 4: hook failed",
        leaving=False,
    )
    assert report_from_msg(report_to_msg(report, wall_time=0.0)) == report


def test_command_and_result_round_trip() -> None:
    from contextros_interfaces.srv import Activate

    request = command_to_request(["A", "B"], ["C"], True, 2.5, "me", "why")
    command = command_from_request(9, request)
    assert (command.request_id, command.activate, command.deactivate) == (9, ("A", "B"), ("C",))
    assert (command.synchronous, command.timeout, command.requester, command.reason) == (
        True,
        2.5,
        "me",
        "why",
    )
    result = ActivationResult(False, "epoch 3 not acknowledged", 3, ("A",), ("/a",), ("/b",), 0.5)
    assert result_from_response(fill_response(Activate.Response(), result)) == result
