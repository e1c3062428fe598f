"""What the synthetic drive produces, one record per camera frame.

These records are the contract between the world/renderer (``drive.py``) and the
MCAP writer (``mcap_writer.py``) and the preview (``preview.py``). Poses follow ROS
conventions (``base_link``: x forward, y left, z up); 3D lanes are in the lane frame
of DESIGN.md (x right, y forward, z up), as the clip store will hold them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lanelab.lanes import Lane


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera rigidly mounted on the ego vehicle.

    K: (3, 3) intrinsics in pixels. T_base_cam: (4, 4) maps points of the camera's
    optical frame (OpenCV: x right, y down, z forward) into ``base_link``.
    """

    K: np.ndarray
    width: int
    height: int
    T_base_cam: np.ndarray
    frame_id: str = "camera_front_optical"


@dataclass(frozen=True)
class Lane2D:
    """A noisy near-range 2D lane detection (the auto-labeler's input).

    uv: (P, 2) float32 pixel coordinates, top to bottom not required.
    """

    uv: np.ndarray
    score: float
    category: int


@dataclass
class SynthFrame:
    """One camera frame of a synthetic drive.

    image: (H, W, 3) uint8, BGR (OpenCV order).
    T_world_base: (4, 4) ego pose, ``odom`` <- ``base_link``, at ``timestamp_ns``.
    lanes: the ground truth in the lane frame of that pose; a point's visibility is 0 where it
    is outside the image, behind an occluding vehicle or hidden behind a crest.
    occluders: (H, W) bool, the pixels that show a vehicle or a roadside object (a segmentation
    network's occluder mask); None: not made.
    """

    index: int
    timestamp_ns: int
    image: np.ndarray
    T_world_base: np.ndarray
    lanes: list[Lane]
    lanes2d: list[Lane2D]
    tags: dict[str, str] = field(default_factory=dict)
    occluders: np.ndarray | None = None
