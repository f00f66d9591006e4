"""Participants read the manager's states from their bytes (status_wire.StateDecoder) exactly
as rclpy reads them; damaged bytes give a ValueError naming the field, never another
exception; the bytes seen last are decoded once for the whole process."""

from __future__ import annotations

import pytest
from contextros_interfaces.msg import LayerState as LayerStateMsg
from rclpy.serialization import deserialize_message, serialize_message

from contextros.protocol import LayerState
from contextros.ros import status_wire
from contextros.ros.messages import state_from_msg, state_to_msg
from contextros.ros.status_wire import StateDecoder
from tests.ros.wire_damage import check_damaged_bytes

STATES = [
    LayerState(epoch=0),
    LayerState(epoch=5, active=("Indoor",), requester="bench", manager_id="m-1", stamp=1.5),
    LayerState(
        epoch=2**64 - 1,
        active=("Outdoor", "Gps ✗", "", "Sky"),
        requester="contextros-cli",
        reason="rule 'dark' at rules/robot.rules:3:1",
        manager_id="4711-0b5e",
        stamp=1_795_757_232.143290532,
        status_period=12.5,
    ),
]


def _bytes(state: LayerState) -> bytes:
    data: bytes = serialize_message(state_to_msg(state, state.stamp))
    return data


def _by_rclpy(data: bytes) -> LayerState:
    return state_from_msg(deserialize_message(data, LayerStateMsg))


@pytest.mark.parametrize("state", STATES)
def test_a_state_reads_as_rclpy_reads_it(state: LayerState) -> None:
    data = _bytes(state)
    ours, theirs = StateDecoder().decode(data), _by_rclpy(data)
    assert ours == theirs == state
    assert (ours.stamp, ours.manager_id) == (theirs.stamp, theirs.manager_id)
    assert ours.status_period == theirs.status_period == state.status_period


def test_the_same_bytes_are_decoded_once_and_the_memory_is_bounded() -> None:
    decoder = StateDecoder()
    data = _bytes(STATES[1])
    first = decoder.decode(data)
    assert decoder.decode(bytes(bytearray(data))) is first  # equal bytes, another object
    for epoch in range(1, 3 * status_wire._STATES_KEPT):
        decoder.decode(_bytes(LayerState(epoch=epoch)))
    assert len(decoder._known) <= status_wire._STATES_KEPT
    huge = LayerState(epoch=9, reason="x" * status_wire._STATE_BYTES_KEPT)
    assert decoder.decode(_bytes(huge)) == huge
    assert _bytes(huge) not in decoder._known


def test_another_encoding_is_read_by_rclpy_or_refused_with_a_value_error() -> None:
    data = b"\x00\x07" + _bytes(STATES[2])[2:]  # an encapsulation nobody wrote
    assert StateDecoder().decode(data) == _by_rclpy(data)
    big_endian = b"\x00\x00" + data[2:]
    try:
        theirs = _by_rclpy(big_endian)
    except RuntimeError:
        with pytest.raises(ValueError, match="state not readable"):
            StateDecoder().decode(big_endian)
    else:
        assert StateDecoder().decode(big_endian) == theirs
    with pytest.raises(ValueError, match="state not readable"):
        StateDecoder().decode(b"")


def test_damaged_states_give_a_value_error_naming_the_field_or_read_as_rclpy() -> None:
    def read(data: bytes) -> tuple[LayerState, float, str]:  # with what equality leaves out
        state = StateDecoder().decode(data)
        return state, state.stamp, state.manager_id

    def by_rclpy(data: bytes) -> tuple[LayerState, float, str]:
        state = _by_rclpy(data)
        return state, state.stamp, state.manager_id

    check_damaged_bytes(_bytes(STATES[2]), read, by_rclpy, "state", 26)


def test_a_huge_claimed_count_is_refused_at_once() -> None:
    data = bytearray(_bytes(LayerState(epoch=1, active=("A",))))
    data[12:16] = (2**32 - 1).to_bytes(4, "little")  # after the header and the epoch
    with pytest.raises(ValueError, match="state field active_layers claims 4294967295"):
        StateDecoder().decode(bytes(data))


def test_the_decoder_knows_every_field_of_the_message() -> None:
    """A field added to LayerState.msg must be read by StateDecoder too (status_wire), or
    Python participants would silently ignore it."""
    assert LayerStateMsg.get_fields_and_field_types() == {
        "epoch": "uint64",
        "active_layers": "sequence<string>",
        "stamp": "builtin_interfaces/Time",
        "requester": "string",
        "reason": "string",
        "manager_id": "string",
        "status_period": "float",
    }
