"""One ONCE-3DLanes label file -> the time, K, T_lane_cam and lanes of a clip-store frame.

The label gives lanes in the camera frame and a projection matrix ``[K | 0]``; it has no
extrinsic, so every frame takes the fixed camera of the store (:func:`lanelab.once.camera.fixed_T_lane_cam`,
LATR's height and pitch). The lanes are moved into the lane frame and sorted near to far
(y ascending); those listed far to near are recorded (:mod:`lanelab.openlane.lane_order`) so
that ground truth written back lists them as the label did. ONCE-3DLanes has no lane categories
(category 0, unknown), no visibility (1 everywhere) and no lane identities.
A label is named by its frame's time in milliseconds (``1616005402699.json``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lanelab.json_files import LaneFileError
from lanelab.lanes import Lane
from lanelab.once.camera import camera_to_lane
from lanelab.once.labels import read_label
from lanelab.openlane.lane_order import near_to_far

NS_PER_MS = 1_000_000
UNKNOWN_CATEGORY = 0


@dataclass(frozen=True)
class LabeledFrame:
    """A label in lanelab's terms. K: (3, 3). lanes: lane frame, y ascending, float32 points.
    far_to_near: the indices of the lanes the label lists far to near."""

    timestamp_ns: int
    K: np.ndarray
    lanes: list[Lane]
    far_to_near: tuple[int, ...]


def timestamp_ns(path: str | os.PathLike[str]) -> int:
    """The time of a label from its name: '1616005402699.json' (milliseconds) -> ns."""
    stem = Path(path).stem
    if not stem.isdigit():
        raise LaneFileError(path, "the file name is not a ONCE frame stamp (milliseconds, digits only)")
    return int(stem) * NS_PER_MS


def read_labeled_frame(path: str | os.PathLike[str], T_lane_cam: np.ndarray) -> LabeledFrame:
    """Read a label (validated by :func:`lanelab.once.labels.read_label`) for a camera of
    extrinsic T_lane_cam (4, 4); LaneFileError names the file and the fault."""
    label = read_label(path)
    lanes, far_to_near = [], []
    for i, camera_points in enumerate(label.lanes):
        points = camera_to_lane(camera_points, T_lane_cam)
        order, reversed_in_file = near_to_far(points)
        lanes.append(Lane(points[order].astype(np.float32), np.ones(len(points), np.float32), UNKNOWN_CATEGORY))
        if reversed_in_file:
            far_to_near.append(i)
    return LabeledFrame(timestamp_ns(path), label.K, lanes, tuple(far_to_near))
