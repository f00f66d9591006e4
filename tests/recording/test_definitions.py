"""The schemas `contextros record` writes decode what rclpy serialized (as rosbag2's do)."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mcap_ros2")
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from sensor_msgs.msg import NavSatFix

from contextros.recording.definitions import (
    SEPARATOR,
    DefinitionError,
    message_definition,
)


def decode(type_name: str, data: bytes) -> object:
    definition = message_definition(type_name).encode()
    schema = Schema(id=1, name=type_name, encoding="ros2msg", data=definition)
    decoder = DecoderFactory().decoder_for("cdr", schema)
    assert decoder is not None
    return decoder(data)


def test_a_nested_message_round_trips_through_its_definition() -> None:
    fix = NavSatFix(latitude=35.7, longitude=139.7, altitude=40.0)
    fix.header.frame_id = "gps"
    fix.header.stamp.sec = 12
    fix.status.status = 2
    fix.position_covariance[4] = 0.5
    decoded = decode("sensor_msgs/msg/NavSatFix", serialize_message(fix))
    assert (decoded.latitude, decoded.longitude, decoded.altitude) == (35.7, 139.7, 40.0)
    assert (decoded.header.frame_id, decoded.header.stamp.sec) == ("gps", 12)
    assert decoded.status.status == 2 and decoded.position_covariance[4] == 0.5
    text = message_definition("sensor_msgs/msg/NavSatFix")
    used = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert used == [
        "MSG: std_msgs/Header",
        "MSG: sensor_msgs/NavSatStatus",
        "MSG: builtin_interfaces/Time",
    ]
    assert text.count(SEPARATOR) == 3


def test_the_protocols_own_messages_have_definitions() -> None:
    pytest.importorskip("contextros_interfaces")
    from contextros_interfaces.msg import LayerState

    state = LayerState(epoch=7, active_layers=["Indoor", "Night"], requester="rule GpsFix")
    decoded = decode("contextros_interfaces/msg/LayerState", serialize_message(state))
    assert (decoded.epoch, decoded.active_layers, decoded.requester) == (
        7,
        ["Indoor", "Night"],
        "rule GpsFix",
    )


def test_an_unknown_type_is_a_clear_error() -> None:
    with pytest.raises(DefinitionError, match=r"no no_such_msgs/msg/Thing\.msg in the installed"):
        message_definition("no_such_msgs/msg/Thing")
    with pytest.raises(DefinitionError, match="is not a message type name"):
        message_definition("Thing")
