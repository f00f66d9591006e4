"""Recordings of a running system, in MCAP (rosbag2's default storage; Foxglove opens it).

`contextros record` writes the protocol's topics and the rules' input topics
(`contextros.ros.recorder`); `read_recording` reads any ROS 2 MCAP file back, decoded
without ROS (the `mcap` and `mcap-ros2-support` packages), for `contextros rules replay`.
"""

from contextros.recording.reader import RecordedMessage, RecordingError, read_recording

__all__ = ["RecordedMessage", "RecordingError", "read_recording"]
