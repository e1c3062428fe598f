"""A clip-store frame's ONCE-3DLanes files: its ground truth and a prediction, in camera coordinates.

Both lie at the frame's relative label path (:func:`~lanelab.once.file_paths.store_label_path`)
under their folders, as the official evaluator pairs them. Lanes are moved from the lane frame
into the frame's camera with its own ``T_lane_cam`` (for a ``lanelab-once`` store, the fixed camera
the labels were read with, so the ground truth comes back as the source labels, point for point up
to the store's float32); ground-truth lanes are listed in the source's point order
(:func:`lanelab.openlane.lane_order.source_order`). Files are written atomically.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from lanelab.lanes import Lane
from lanelab.once.camera import lane_to_camera
from lanelab.once.file_paths import json_file, store_label_path
from lanelab.once.labels import label_json, prediction_json
from lanelab.openlane.lane_order import source_order
from lanelab.openlane.write import write_json
from lanelab.store import ClipStore, FrameRecord


def write_ground_truth(gt_dir: str | os.PathLike[str], clip_id: str, frame: FrameRecord) -> Path:
    """Write a labeled frame's lanes and calibration ``[K | 0]`` as a ONCE label under gt_dir; its path."""
    path = json_file(gt_dir, store_label_path(clip_id, frame.timestamp_ns, frame.tags))
    lanes = [lane_to_camera(lane.points, frame.T_lane_cam) for lane in source_order(frame.lanes, frame.tags)]
    write_json(path, label_json(lanes, frame.K))
    return path


def write_prediction(
    pred_dir: str | os.PathLike[str], clip_id: str, frame: FrameRecord, lanes: Sequence[Lane]
) -> Path:
    """Write lanes predicted for a frame (points (P, 3) in its lane frame, each with its score) as a
    ONCE prediction file under pred_dir; its path."""
    path = json_file(pred_dir, store_label_path(clip_id, frame.timestamp_ns, frame.tags))
    camera = [lane_to_camera(np.asarray(lane.points, np.float64), frame.T_lane_cam) for lane in lanes]
    write_json(path, prediction_json(camera, [lane.score for lane in lanes]))
    return path


def export_ground_truth(store: str | os.PathLike[str], split: str, gt_dir: str | os.PathLike[str]) -> list[Path]:
    """Write the ground truth of every labeled frame of a store's split under gt_dir; the paths."""
    clips = ClipStore(store)
    return [
        write_ground_truth(gt_dir, clip.clip_id, frame)
        for clip in clips.clips_in(split)
        for frame in clips.read_frames(clip.clip_id)
        if frame.labeled
    ]
