"""Helpers of the ingestor's tests: small synthetic configs, running the ingestor, rewriting logs.

``small_config(*overrides)``: log 0 of seed 0 is 2 s at 10 fps, 160 x 120, a label on every
third frame, 64 kB chunks so that a log has several. ``ingest_into(store, input, *overrides)``
runs the ingestor as ``lanelab-ingest`` does. ``read_log`` / ``write_log`` rewrite a log
message by message with the ``mcap`` library alone, so that damaged logs are what another
writer could produce.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from data_ingest.ingest.config import load_ingest_config
from data_ingest.ingest.ingest import ingest
from data_ingest.ingest.log_result import LogResult
from data_ingest.synth.config import SynthConfig, load_synth_config, start_time_ns
from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.frame import CameraModel, SynthFrame

SMALL = ["duration_s=2.0", "fps=10", "tf_rate_hz=50", "label_every=3", "camera.width=160",
         "camera.height=120", "chunk_size=65536"]
ENCODINGS = {
    "ros2": ["encoding=ros2"],
    "foxglove-protobuf": ["encoding=foxglove", "foxglove_schema=protobuf"],
    "foxglove-json": ["encoding=foxglove", "foxglove_schema=json"],
}
LOG_NAME = "synth_s0_000.mcap"


def small_config(*overrides: str) -> SynthConfig:
    return load_synth_config([*SMALL, *overrides])


START_NS = start_time_ns(small_config(), 0)  # the sensor time of a test log's drive time 0 (log_index 0)


@dataclass(frozen=True)
class CachedDrive:
    """A drive rendered once, for the MCAP writer (``DriveSource``) and as ground truth (``truth``)."""

    camera: CameraModel
    duration_ns: int
    scenario: dict[str, str]
    truth: list[SynthFrame]
    pose_at: Callable[[int], np.ndarray]

    @classmethod
    def render(cls, drive: SyntheticDrive) -> CachedDrive:
        return cls(drive.camera, drive.duration_ns, drive.scenario, list(drive.frames()), drive.pose_at)

    def frames(self) -> Iterator[SynthFrame]:
        return iter(self.truth)


def ingest_into(store: Path, input_: Path | str, *overrides: str) -> list[LogResult]:
    """Ingest ``input_`` into ``store`` with conf/ingest.yaml and ``overrides``."""
    return ingest(load_ingest_config([f"input={input_}", f"output={store}", *overrides]))


@dataclass(frozen=True)
class LogMessage:
    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    log_time: int
    data: bytes


def read_log(path: Path) -> list[LogMessage]:
    """Every message of a log, in file order."""
    with open(path, "rb") as handle:
        return [LogMessage(channel.topic, schema.name, schema.encoding, schema.data, channel.message_encoding,
                           message.log_time, message.data)
                for schema, channel, message in make_reader(handle).iter_messages(log_time_order=False)]


def write_log(path: Path, messages: list[LogMessage], chunk_size: int = 65536) -> Path:
    """Write ``messages`` in list order (one channel per topic) as an MCAP file with zstd chunks."""
    with open(path, "wb") as handle:
        writer = Writer(handle, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        writer.start()
        schemas: dict[tuple, int] = {}
        channels: dict[str, int] = {}
        for m in messages:
            schema = (m.schema_name, m.schema_encoding, m.schema_data)
            if schema not in schemas:
                schemas[schema] = writer.register_schema(*schema)
            if m.topic not in channels:
                channels[m.topic] = writer.register_channel(m.topic, m.message_encoding, schemas[schema])
            writer.add_message(channels[m.topic], log_time=m.log_time, data=m.data, publish_time=m.log_time)
        writer.finish()
    return path


def chunk_spans(path: Path) -> list[tuple[int, int]]:
    """(start, length) of each chunk record, from the log's summary."""
    with open(path, "rb") as handle:
        summary = make_reader(handle).get_summary()
    return [(index.chunk_start_offset, index.chunk_length) for index in summary.chunk_indexes]
