"""One pass over a drive log: the messages the ingestor needs, decoded; image bytes set aside.

Every topic of the options is read in one pass (:func:`scan_log`). Image bytes go to a
:class:`~data_ingest.ingest.spill.Spill`; only their stamps, frames and sizes stay in
memory. A topic whose schema is unknown, or a required topic without messages, makes
the log unusable (:class:`LogError`); a single message that cannot be decoded is counted
and skipped.
"""

from __future__ import annotations

from collections import Counter
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from data_ingest.contract import CALIBRATION, IMAGE, LANES, LANES2D, OCCLUDERS, TAGS, TRANSFORMS
from data_ingest.ingest.config import LogReading
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.mcap_reader import ReadReport, read_messages
from data_ingest.ingest.messages import (
    CalibrationMsg,
    Decoder,
    ImageMsg,
    Lanes2DMsg,
    LanesMsg,
    MessageError,
    TagsMsg,
    check_schema,
    parse_lanes3d,
    type_name,
)
from data_ingest.ingest.spill import Spill, SpillRef
from data_ingest.ingest.tf_tree import TfTree

LABEL_BATCH = 64  # label payloads parsed together (Arrow's JSON reader is fastest on batches)


@dataclass(frozen=True)
class ImageRef:
    """An image of the log; its bytes are in the spill at ``data``."""

    stamp_ns: int
    frame_id: str
    encoding: str
    width: int
    height: int
    data: SpillRef


@dataclass
class LogContents:
    """What a log holds for the ingestor; images in file order, the rest as read."""

    images: list[ImageRef] = field(default_factory=list)
    calibrations: list[CalibrationMsg] = field(default_factory=list)
    tf: TfTree = field(default_factory=TfTree)
    labels: list[LanesMsg] = field(default_factory=list)
    detections: list[Lanes2DMsg] = field(default_factory=list)  # read only for auto-labeling
    occluders: list[ImageMsg] = field(default_factory=list)  # occluder masks, read only for auto-labeling
    tags: list[TagsMsg] = field(default_factory=list)
    dropped: Counter = field(default_factory=Counter)  # image messages unusable, by reason
    bad_messages: Counter = field(default_factory=Counter)  # other messages skipped, by "topic: reason"


def scan_log(path: Path, cfg: LogReading, spill: Spill, report: ReadReport,
             progress: Callable[[int], None] | None = None, detections: bool = False) -> LogContents:
    """Read every message of the configured topics of the log at ``path``; with detections also
    its 2D lane detections and occluder masks (what auto-labeling reads)."""
    topics = cfg.topics
    roles = {topics.image: IMAGE, topics.calibration: CALIBRATION, topics.tf: TRANSFORMS,
             topics.tf_static: TRANSFORMS, topics.lanes: LANES, topics.tags: TAGS}
    if detections:
        roles[topics.lanes2d], roles[topics.occluders] = LANES2D, OCCLUDERS
    contents, decoder = LogContents(tf=TfTree(cfg.tolerances.tf_agreement)), Decoder()
    checked: set[int] = set()
    label_batch: list[bytes] = []
    # Labels are parsed on a second thread while the scan goes on: Arrow's JSON reader releases the GIL.
    with ThreadPoolExecutor(max_workers=1) as label_parser:
        parsed: list[Future] = []
        for raw in read_messages(path, roles, report, progress):
            role = roles[raw.topic]
            if raw.channel.id not in checked:
                check_schema(path, raw.topic, role, raw.schema, raw.channel.message_encoding)
                checked.add(raw.channel.id)
            try:
                if role == LANES:  # parsed in batches
                    label_batch.append(raw.data)
                    if len(label_batch) == LABEL_BATCH:
                        parsed.append(label_parser.submit(parse_lanes3d, label_batch))
                        label_batch = []
                    continue
                record = decoder.decode(raw, role)
                if role == IMAGE:
                    contents.images.append(ImageRef(record.stamp_ns, record.frame_id, record.encoding, record.width,
                                                    record.height, spill.put(record.data)))
                elif role == CALIBRATION:
                    contents.calibrations.append(record)
                elif role == TRANSFORMS:
                    for transform in record:
                        contents.tf.add(transform, static=raw.topic == topics.tf_static)
                elif role == LANES2D:
                    contents.detections.append(record)
                elif role == OCCLUDERS:
                    contents.occluders.append(record)
                else:
                    contents.tags.append(record)
            except MessageError as err:
                if role == IMAGE:
                    contents.dropped[f"image message unusable: {err}"] += 1
                else:
                    contents.bad_messages[f"{raw.topic}: {err}"] += 1
        _check_required(path, cfg, report, detections)
        parsed.append(label_parser.submit(parse_lanes3d, label_batch))
        for label in (label for future in parsed for label in future.result()):
            if isinstance(label, MessageError):
                contents.bad_messages[f"{topics.lanes}: {label}"] += 1
            else:
                contents.labels.append(label)
    return contents


def _check_required(path: Path, cfg: LogReading, report: ReadReport, detections: bool) -> None:
    """Raise :class:`LogError` when the image, calibration or /tf topic has no message, or
    the 2D detections when they are read (auto-labeling); list what the log has."""
    topics = cfg.topics
    missing = [topic for topic in (topics.image, topics.calibration, topics.tf) if report.topics[topic] == 0]
    no_detections = detections and report.topics[topics.lanes2d] == 0
    if not missing and not no_detections:
        return
    if not report.topics:
        if report.break_byte is not None:  # e.g. cut inside its only chunk, which held the channels too
            raise LogError(f"{path}: truncated or unreadable from byte {report.break_byte} of {report.size}, "
                           f"before any complete message ({report.break_reason}): nothing to ingest")
        raise LogError(f"{path}: the log has no channels and no messages")
    if not sum(report.topics.values()) and report.break_byte is None:  # channels, but a recording of nothing
        raise LogError(f"{path}: the log is empty: its {len(report.topics)} channel(s) "
                       f"({', '.join(sorted(report.topics))}) hold no message")
    have = ", ".join(f"{topic} ({type_name(report.schemas.get(topic)) or 'no schema'}, {count} messages)"
                     for topic, count in sorted(report.topics.items()))
    if not missing:
        raise LogError(f"{path}: no 2D lane detections on {topics.lanes2d}, which auto-labeling "
                       f"(autolabel.enabled=true) needs (set topics.lanes2d to the log's lanelab.Lanes2D topic); "
                       f"the log has: {have}")
    raise LogError(f"{path}: missing required topic{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                   f"(set topics.* to the log's names); the log has: {have}")
