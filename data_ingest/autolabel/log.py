"""Auto-labeling inside ``lanelab-ingest``: a log's assembled frames get auto-labels in place of
its ``/lanes``, and where it has those, they score the auto-labels.

The 2D detections (``topics.lanes2d``) and occluder masks (``topics.occluders``, optional) of
the log are matched to its images as labels are (the nearest within ``tolerances.label_s``,
from the image's camera); the frames, all of them before any ``clips.target_fps``
subsampling, are auto-labeled (:func:`~data_ingest.autolabel.pipeline.auto_label`). A frame
whose labels cannot reach ``autolabel.min_reach_m`` is stored unlabeled. Where the log's
true lanes label a frame that is auto-labeled, the pair is scored
(:mod:`~data_ingest.autolabel.quality`) and a few such frames are kept for the pictures.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Sequence, TypeVar

import cv2
import numpy as np

from data_ingest.autolabel.pipeline import DriveFrames, TrajectoryError, auto_label
from data_ingest.autolabel.quality import Quality, metric_config, score_frame, spread
from data_ingest.ingest.assemble import PlannedFrame, nearest_stamp
from data_ingest.ingest.config import IngestConfig
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.messages import ImageMsg, Lanes2DMsg
from data_ingest.ingest.scan import LogContents
from data_ingest.ingest.spill import Spill
from lanelab.store.image_codec import decode_image

Message = TypeVar("Message", Lanes2DMsg, ImageMsg)


def autolabel_log(path: Path, name: str, frames: Sequence[PlannedFrame], contents: LogContents, spill: Spill,
                  cfg: IngestConfig, notes: list[str]) -> tuple[list[PlannedFrame], Quality, str]:
    """The frames with auto-labels, the scored frames (none without true lanes or
    ``autolabel.report``) and a line saying what was labeled. ``name`` names the log in frame
    ids; problems go to ``notes``. Raises LogError when the trajectory jumps or stops."""
    topics, tolerance = cfg.topics, cfg.tolerances.label_s
    records = [frame.record for frame in frames]
    stamps = np.array([record.timestamp_ns for record in records], dtype=np.int64)
    camera = frames[0].image.frame_id
    detections = _matched(contents.detections, stamps, camera, tolerance, topics.lanes2d, notes)
    masks = _matched(contents.occluders, stamps, camera, tolerance, topics.occluders, notes)
    drive = DriveFrames(
        stamps=stamps, K=np.stack([r.K for r in records]), T_lane_cam=np.stack([r.T_lane_cam for r in records]),
        T_world_lane=np.stack([r.T_world_lane for r in records]),
        image_size=np.array([(r.width, r.height) for r in records]),
        detections=[message.lanes if message is not None else [] for message in detections],
        occluded=[_mask(message, notes, topics.occluders) for message in masks] if contents.occluders else None)
    try:
        labels = auto_label(drive, cfg.autolabel)
    except TrajectoryError as err:
        raise LogError(f"{path}: {err}") from None
    summary = (f"{len(labels.lines)} lines tracked, {int(labels.labeled.sum())} of {len(records)} frames labeled"
               + (" (the last ones: the drive ends before their labels reach autolabel.min_reach_m)"
                  if not labels.labeled.all() else ""))
    labeled = [replace(frame, record=replace(frame.record, labeled=bool(ok), lanes=lanes))
               for frame, ok, lanes in zip(frames, labels.labeled, labels.lanes)]
    quality = Quality()
    if not cfg.autolabel.report:
        return labeled, quality, summary
    config = metric_config()
    scored = [i for i, record in enumerate(records) if record.labeled and labels.labeled[i]]
    for i in scored:
        frame_id = f"{name}/{records[i].timestamp_ns}"
        quality.results.append((frame_id, score_frame(records[i].lanes, labels.lanes[i], config)))
        quality.tags[frame_id] = dict(records[i].tags)
    for k in spread(len(scored), cfg.autolabel.pictures):
        i = scored[k]
        image = cv2.cvtColor(decode_image(replace(records[i], image=spill.get(frames[i].image.data))),
                             cv2.COLOR_RGB2BGR)
        quality.add_picture(f"{name} {(stamps[i] - stamps[0]) * 1e-9:.1f} s", image, records[i].K,
                            records[i].T_lane_cam, records[i].lanes, labels.lanes[i])
    return labeled, quality, summary


def _matched(messages: Sequence[Message], stamps: np.ndarray, camera: str, tolerance_s: float, topic: str,
             notes: list[str]) -> list[Message | None]:
    """Per image (stamps (N,)), the message of ``camera`` nearest in time within the tolerance, or None."""
    out: list[Message | None] = [None] * len(stamps)
    mine = [message for message in messages if message.frame_id == camera]
    if len(mine) < len(messages):
        notes.append(f"{topic}: {len(messages) - len(mine)} messages of another camera than the images' "
                     f"{camera!r}: ignored")
    if not mine:
        return out
    message_stamps = np.array([message.stamp_ns for message in mine], dtype=np.int64)
    frame = nearest_stamp(stamps, message_stamps)
    near = np.abs(stamps[frame] - message_stamps) <= tolerance_s * 1e9
    for k in np.flatnonzero(near):
        f = int(frame[k])
        if out[f] is None or abs(message_stamps[k] - stamps[f]) < abs(out[f].stamp_ns - stamps[f]):
            out[f] = mine[k]
    return out


def _mask(message: ImageMsg | None, notes: list[str], topic: str) -> np.ndarray | None:
    """An occluder mask (H, W) bool from its image message (non-zero pixels), None if there is none or it is garbled."""
    if message is None:
        return None
    try:
        return decode_image(_Encoded(message)).any(axis=-1)
    except ValueError as err:
        notes.append(f"{topic}: a mask at {message.stamp_ns} ns cannot be decoded ({err}): frame labeled without it")
        return None


class _Encoded:
    """An image message as :func:`decode_image` reads a stored image."""

    def __init__(self, message: ImageMsg) -> None:
        self.image, self.image_encoding = message.data, message.encoding
        self.width, self.height = message.width, message.height

