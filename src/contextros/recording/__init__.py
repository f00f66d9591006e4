"""Recordings of a running system, in MCAP (rosbag2's default storage; Foxglove opens it).

`contextros record` writes the protocol's topics and the rules' input topics
(`contextros.ros.recorder`) through `RecordingWriter`, so a recorder killed without warning
leaves a readable file; `read_recording` reads any ROS 2 MCAP file back, decoded without
ROS (the `mcap` and `mcap-ros2-support` packages), for `contextros rules replay`, a
truncated one up to where it ends; `repair_recording` (`contextros repair`) writes a
complete copy of a truncated file.
"""

from contextros.recording.reader import Damage, RecordedMessage, RecordingError, read_recording
from contextros.recording.repair import Repair, repair_recording
from contextros.recording.writer import RecordingWriter

__all__ = [
    "Damage",
    "RecordedMessage",
    "RecordingError",
    "RecordingWriter",
    "Repair",
    "read_recording",
    "repair_recording",
]
