"""The MCAP file lanelab-predict writes: messages copied from a log as they are (schema,
channel metadata, times and sequence kept) and the channels of the predictions."""

from __future__ import annotations

from collections import Counter
from typing import BinaryIO

from mcap.writer import LIBRARY_IDENTIFIER, CompressionType
from mcap.writer import Writer as McapWriter

import lanelab
from data_ingest.ingest.mcap_reader import RawMessage
from data_ingest.synth.encoders import Schema

CHUNK_SIZE = 1 << 20


class OutputLog:
    """An MCAP file being written to ``stream``, zstd chunks; ``profile`` of its header
    ("ros2" where ROS 2 messages are copied)."""

    def __init__(self, stream: BinaryIO, profile: str) -> None:
        self._mcap = McapWriter(stream, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        self._mcap.start(profile=profile, library=f"lanelab-predict/{lanelab.__version__} {LIBRARY_IDENTIFIER}")
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._copied: dict[int, int] = {}  # the log's channel id -> this file's
        self._channels: dict[str, int] = {}  # topic -> channel id
        self.counts: Counter = Counter()  # messages per topic

    def _schema_id(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding, bytes(data))
        if key not in self._schemas:
            self._schemas[key] = self._mcap.register_schema(name, encoding, key[2])
        return self._schemas[key]

    def copy(self, message: RawMessage) -> None:
        """Write a message of the log as it came."""
        channel = message.channel
        if channel.id not in self._copied:
            schema = message.schema
            schema_id = 0 if schema is None else self._schema_id(schema.name, schema.encoding, schema.data)
            self._copied[channel.id] = self._mcap.register_channel(
                channel.topic, channel.message_encoding, schema_id, dict(channel.metadata))
        self._mcap.add_message(self._copied[channel.id], log_time=message.log_time, data=message.data,
                               publish_time=message.publish_time, sequence=message.sequence)
        self.counts[channel.topic] += 1

    def add_channel(self, topic: str, schema: Schema, message_encoding: str) -> None:
        self._channels[topic] = self._mcap.register_channel(
            topic, message_encoding, self._schema_id(schema.name, schema.encoding, schema.data))

    def write(self, topic: str, log_time: int, data: bytes) -> None:
        """Write a message on a channel of :meth:`add_channel`."""
        self._mcap.add_message(self._channels[topic], log_time=log_time, data=data, publish_time=log_time,
                               sequence=self.counts[topic])
        self.counts[topic] += 1

    def finish(self) -> None:
        self._mcap.finish()
