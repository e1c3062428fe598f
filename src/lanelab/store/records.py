"""A clip file's rows as Python objects: a frame and the lanes (:class:`lanelab.lanes.Lane`) labeled in it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lanelab.lanes import Lane


@dataclass(eq=False)
class FrameRecord:
    """One row of a clip file: a camera frame with its calibration, pose and labels.

    K: (3, 3) float64 intrinsics in pixels. T_lane_cam: (4, 4) float64 camera extrinsic
    (maps camera points into the lane frame). T_world_lane: (4, 4) float64 ego pose.
    ``lanes`` is empty when ``labeled`` is False (temporal history only).
    """

    timestamp_ns: int
    image: bytes
    image_encoding: str
    width: int
    height: int
    K: np.ndarray
    T_lane_cam: np.ndarray
    T_world_lane: np.ndarray
    labeled: bool
    lanes: list[Lane] = field(default_factory=list)
    tags: dict[str, str] = field(default_factory=dict)
