"""Writing MCAP so that a killed writer leaves a readable file.

The mcap writer keeps the open chunk in memory and puts schemas and channels inside the
next chunk, so a recorder killed before its first chunk left 0 bytes, and one killed later
lost everything since its last 64 KiB chunk (40 s at the protocol's 1.5 KB/s). Here the
header, each schema and each channel reach the file at once (as records of the data
section, which MCAP allows between chunks; the summary repeats them), and `close_chunk`,
which the recorder calls every CHUNK_PERIOD, writes the open chunk and flushes: a writer
killed without warning loses at most what it received since (the OS keeps what was
written; no fsync, so a power cut may lose more).
"""

from __future__ import annotations

from typing import Any, BinaryIO

# The open chunk is written at least this often (and whenever it passes CHUNK_SIZE).
CHUNK_PERIOD = 0.25
CHUNK_SIZE = 1024 * 1024


class RecordingWriter:
    """An MCAP writer of ROS 2 recordings (profile `ros2`) onto `stream`, which it does
    not close."""

    def __init__(
        self,
        stream: BinaryIO,
        *,
        profile: str = "ros2",
        library: str = "contextros record",
        chunk_size: int = CHUNK_SIZE,
    ) -> None:
        from mcap.writer import Writer

        self._stream = stream
        writer: Any = Writer(stream, chunk_size=chunk_size, compression=compression())
        writer.start(profile=profile, library=library)
        writer.flush()  # the header on disk now
        self._writer = writer

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        from mcap.records import Schema

        schema_id: int = self._writer.register_schema(name, encoding, data)
        self._write_now(Schema(id=schema_id, name=name, encoding=encoding, data=data))
        return schema_id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        from mcap.records import Channel

        channel_id: int = self._writer.register_channel(topic, message_encoding, schema_id)
        channel = Channel(
            id=channel_id,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata={},
        )
        self._write_now(channel)
        return channel_id

    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int
    ) -> None:
        self._writer.add_message(channel_id, log_time, data, publish_time, sequence)

    def close_chunk(self) -> None:
        """Write the open chunk, if it holds a message, and flush the stream."""
        self._writer.flush()

    def finish(self) -> None:
        """The last chunk, the summary and the footer (the stream stays open)."""
        self._writer.finish()
        self._stream.flush()

    def _write_now(self, record: Any) -> None:
        """`record` into the data section now, after the chunk holding earlier messages."""
        from mcap.data_stream import RecordBuilder

        self._writer.flush()
        builder: Any = RecordBuilder()
        record.write(builder)
        self._stream.write(builder.end())
        self._stream.flush()


def compression() -> Any:
    """zstd, as rosbag2 writes, when the zstandard package is there; else none."""
    from mcap.writer import CompressionType

    try:
        import zstandard  # noqa: F401 - only whether it is there
    except ImportError:
        return CompressionType.NONE
    return CompressionType.ZSTD
