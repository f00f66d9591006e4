"""The manager reads statuses from their bytes (status_wire) exactly as rclpy reads them, and
damaged bytes give a ValueError naming the field, never another exception."""

from __future__ import annotations

import pytest
from contextros_interfaces.msg import ParticipantStatus
from rclpy.serialization import deserialize_message, serialize_message

from contextros.protocol import LayerDeclaration, ParticipantReport
from contextros.ros.messages import report_from_msg, report_to_msg
from contextros.ros.status_wire import StatusDecoder, StatusEncoder
from tests.ros.wire_damage import check_damaged_bytes

REPORTS = [
    ParticipantReport(node="/a"),
    ParticipantReport(
        node="/robot/cleaner",
        incarnation="4711-0b5e",
        layers=(
            LayerDeclaration("Indoor", excludes=frozenset({"Outdoor"}), group="place"),
            LayerDeclaration(
                "Gps",
                requires=frozenset({"Outdoor", "Sky"}),
                after=frozenset({"Outdoor"}),
            ),
            LayerDeclaration("Outdoor", excludes=frozenset({"Indoor"}), group="place"),
        ),
        applied_epoch=2**40 + 3,
        applied_manager_id="m-1",
        active=("Indoor", "Gps"),
        in_critical_section=True,
        pending_epoch=7,
        failed_epoch=5,
        error="hook of Gps: gps not found ✗",
        leaving=False,
        hosted=("/robot/wheels", "/robot/camera"),
        manager_lost=True,
        vote_epoch=9,
        vote_yes=True,
        vote_reason="",
        vote_manager_id="m-1",
    ),
    ParticipantReport(node="/b", incarnation="x", leaving=True, vote_reason="no: busy"),
]


def _bytes(report: ParticipantReport, wall_time: float = 1.5e9) -> bytes:
    return serialize_message(report_to_msg(report, wall_time))


def _by_rclpy(data: bytes) -> ParticipantReport:
    return report_from_msg(deserialize_message(data, ParticipantStatus))


@pytest.mark.parametrize("report", REPORTS, ids=["minimal", "everything", "leaving"])
def test_a_status_reads_as_rclpy_reads_it(report: ParticipantReport) -> None:
    data = _bytes(report)
    assert data[:2] == b"\x00\x01", "the fast path is taken (CDR, little endian)"
    assert StatusDecoder().decode(data) == _by_rclpy(data) == report


def test_repeated_declarations_are_decoded_once_and_changed_ones_again() -> None:
    decoder = StatusDecoder()
    report = REPORTS[1]
    first = decoder.decode(_bytes(report, 1.0))
    later = decoder.decode(_bytes(report, 2.0))  # another stamp: the same declarations
    assert later.layers is first.layers
    changed = (*report.layers[:2], LayerDeclaration("Outdoor", group="place"))
    other = decoder.decode(_bytes(ParticipantReport(**{**vars(report), "layers": changed}), 3.0))
    assert other.layers == changed and other.layers is not first.layers
    # Another node with the same name's length and other declarations is not confused.
    renamed = ParticipantReport(**{**vars(report), "node": "/robot/cleanes", "layers": ()})
    assert decoder.decode(_bytes(renamed)).layers == ()


def test_invalid_utf8_is_replaced_and_a_nul_ends_a_string_as_rclpy_reads_them() -> None:
    data = _bytes(ParticipantReport(node="/forgerX", incarnation="1"))
    invalid = data.replace(b"/forgerX", b"/forger\xff")
    assert StatusDecoder().decode(invalid).node == "/forger\ufffd" == _by_rclpy(invalid).node
    cut = data.replace(b"/forgerX", b"/forg\x00rX")
    assert StatusDecoder().decode(cut).node == "/forg" == _by_rclpy(cut).node


def test_another_encoding_is_read_by_rclpy_or_refused_with_a_value_error() -> None:
    data = _bytes(REPORTS[1])
    with pytest.raises(ValueError, match="status not readable"):
        StatusDecoder().decode(b"\x00\x07" + data[2:])  # an encapsulation nobody wrote
    with pytest.raises(ValueError, match="status not readable"):
        StatusDecoder().decode(b"")


def test_damaged_statuses_give_a_value_error_naming_the_field_or_read_as_rclpy() -> None:
    check_damaged_bytes(_bytes(REPORTS[1]), StatusDecoder().decode, _by_rclpy, "status", 16)


def test_a_huge_claimed_count_is_refused_at_once() -> None:
    data = bytearray(_bytes(ParticipantReport(node="/a", incarnation="b")))
    # After the header (4 bytes), node ("/a": 4 + 3 bytes, padded to 12) and incarnation
    # ("b": 4 + 2 bytes, padded to 20): the layers' count.
    data[20:24] = (2**32 - 1).to_bytes(4, "little")
    with pytest.raises(ValueError, match="status field layers claims 4294967295 entries"):
        StatusDecoder().decode(bytes(data))


@pytest.mark.parametrize("report", REPORTS, ids=["minimal", "everything", "leaving"])
def test_a_status_written_as_bytes_is_the_message_rclpy_would_write(
    report: ParticipantReport,
) -> None:
    """What a participant publishes (StatusEncoder) deserializes, through rclpy, to exactly
    the message `report_to_msg` builds, and reads back as the same report."""
    encoder = StatusEncoder()
    for wall_time in (1.7e9 + 0.123456789, 0.0, 1.7e9 + 0.5):  # the prefix reused
        data = encoder.encode(report, wall_time)
        assert deserialize_message(data, ParticipantStatus) == report_to_msg(report, wall_time)
        assert StatusDecoder().decode(data) == report


def test_the_encoded_prefix_follows_a_change_of_declarations() -> None:
    encoder = StatusEncoder()
    report = REPORTS[1]
    encoder.encode(report, 1.0)
    changed = ParticipantReport(**{**vars(report), "layers": report.layers[:1]})
    assert StatusDecoder().decode(encoder.encode(changed, 2.0)).layers == report.layers[:1]
    restarted = ParticipantReport(**{**vars(report), "incarnation": "4712-0b5e"})
    assert StatusDecoder().decode(encoder.encode(restarted, 3.0)).incarnation == "4712-0b5e"


def test_a_string_without_its_terminator_reads_as_rclpy_reads_it() -> None:
    data = bytearray(_bytes(ParticipantReport(node="/abcX", incarnation="1")))
    data[13] = ord("Q")  # node: length 6 at 4..8, then "/abcX\0" at 8..14: its NUL goes
    assert StatusDecoder().decode(bytes(data)).node == "/abcXQ"
    assert StatusDecoder().decode(bytes(data)).node == _by_rclpy(bytes(data)).node


def test_what_the_decoder_keeps_is_bounded_whatever_the_senders_make_up() -> None:
    """Declarations are kept before any check: statuses too large to be accepted are not
    kept at all, and a flood under ever new names costs a bounded amount."""
    import tracemalloc

    import contextros.ros.status_wire as wire

    empty = tuple(LayerDeclaration(f"L{index}") for index in range(300))  # > MAX_LAYERS
    decoder = StatusDecoder()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for index in range(40):
            decoder.decode(_bytes(ParticipantReport(node=f"/huge{index}", layers=empty)))
        kept = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert kept < 1_000_000, f"{kept} bytes kept for statuses no manager accepts"
    some = tuple(LayerDeclaration(f"L{index}") for index in range(200))
    for index in range(120):
        decoder.decode(_bytes(ParticipantReport(node=f"/flood{index}", layers=some)))
        assert decoder._cached_declarations <= wire._CACHE_DECLARATIONS
        assert decoder._cached_bytes <= wire._CACHE_BYTES
