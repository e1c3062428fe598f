"""Reading and validating OpenLane 3D-lane JSON files (ground truth and predictions).

The layout is the one of the official evaluator (OpenDriveLab/OpenLane,
``eval/LANE_evaluation/lane3d/eval_3D_lane.py``):

- a ground-truth file has ``file_path``, ``extrinsic`` (4, 4), ``intrinsic`` (3, 3) and
  ``lane_lines``, each lane with ``xyz`` (3, N) in the camera frame, ``visibility`` (N,) and
  ``category``;
- a prediction file has ``file_path`` and ``lane_lines``, each lane with ``xyz`` (N, 3) in the
  evaluator's ground frame (x right, y forward, z up) and ``category``; as in the official
  evaluator, N x 2 lanes get z = 0 and columns past the third are ignored. Any other key
  (``visibility``, scores...) is ignored.

Every problem is reported as an :class:`OpenLaneFormatError` that names the file.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lanelab.metrics.json_files import (
    LaneFileError,
    load_json_object,
    numeric_array,
    require,
    require_list,
)

# OpenLane stores lanes in the Waymo camera axes (x forward, y left, z up); this matrix maps
# OpenCV camera axes (x right, y down, z forward) to them, and its transpose maps back.
_WAYMO_FROM_OPENCV = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
_OPENCV_FROM_WAYMO = _WAYMO_FROM_OPENCV.T.copy()
# Vehicle axes (x forward, y left, z up) from ground axes (x right, y forward, z up).
_VEHICLE_FROM_GROUND = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
# Ground-style camera axes (x right, y forward, z up) from OpenCV camera axes.
_GROUND_FROM_OPENCV = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


# The error every OpenLane reader raises (the name users of evaluate() catch).
OpenLaneFormatError = LaneFileError


@dataclass(frozen=True)
class GroundTruthFrame:
    """One ground-truth frame, lanes already in the evaluator's ground frame.

    lanes[i]: (N_i, 3) points (x right, y forward, z up), visibility[i]: (N_i,),
    categories[i]: OpenLane category id.
    """

    file_path: str
    lanes: list[np.ndarray]
    visibility: list[np.ndarray]
    categories: list[int]


@dataclass(frozen=True)
class PredictionFrame:
    """One prediction frame: lanes[i] is (N_i, 3) (or (N_i, 2): z = 0) in the ground frame."""

    file_path: str
    lanes: list[np.ndarray]
    categories: list[int]


def ground_from_camera(extrinsic: np.ndarray) -> np.ndarray:
    """The official evaluator's ground-from-camera transform (4, 4) for a GT extrinsic (4, 4).

    The extrinsic maps Waymo camera axes into the vehicle frame. The evaluator re-expresses
    its rotation to map OpenCV camera axes into ground axes (x right, y forward, z up), and
    keeps only the camera height of its translation: the ground frame lies under the camera,
    not under the vehicle origin (official ``cam_extrinsics[0:2, 3] = 0``).
    """
    T = np.array(extrinsic, dtype=np.float64)
    R = T[:3, :3]
    # Signed permutation matrices: these products only move and negate entries, exactly.
    T[:3, :3] = _VEHICLE_FROM_GROUND.T @ R @ _VEHICLE_FROM_GROUND @ _GROUND_FROM_OPENCV
    T[0:2, 3] = 0.0
    return T


def camera_lane_to_ground(xyz: np.ndarray, ground_T_camera: np.ndarray) -> np.ndarray:
    """Lane points (3, N) in Waymo camera axes -> (N, 3) in the ground frame.

    Computed as the official ``E @ (inv(C) @ [xyz; 1])`` with the same (4, 4) @ (4, N)
    products, so that the floating-point result is the same.
    """
    homogeneous = np.vstack([xyz, np.ones((1, xyz.shape[1]))])
    return np.matmul(ground_T_camera, np.matmul(_OPENCV_FROM_WAYMO, homogeneous))[0:3, :].T


def read_ground_truth(path: str | os.PathLike[str]) -> GroundTruthFrame:
    """Read and validate one ground-truth JSON and convert its lanes to the ground frame."""
    data = load_json_object(path)
    file_path = require(data, "file_path", path)
    if not isinstance(file_path, str):
        raise OpenLaneFormatError(path, "'file_path' must be a string")
    extrinsic = numeric_array(require(data, "extrinsic", path), (4, 4), "'extrinsic'", path)
    numeric_array(require(data, "intrinsic", path), (3, 3), "'intrinsic'", path)
    T = ground_from_camera(extrinsic)

    lanes, visibility, categories = [], [], []
    for i, lane in enumerate(require_list(data, "lane_lines", path)):
        where = f"lane_lines[{i}]"
        xyz = numeric_array(require(lane, "xyz", path, where), (3, None), f"{where}.xyz", path)
        vis = numeric_array(
            require(lane, "visibility", path, where), (None,), f"{where}.visibility", path
        )
        if vis.shape[0] != xyz.shape[1]:
            raise OpenLaneFormatError(
                path, f"{where}: {vis.shape[0]} visibility values for {xyz.shape[1]} points"
            )
        lanes.append(camera_lane_to_ground(xyz, T))
        visibility.append(vis)
        categories.append(_category(lane, path, where, strict=True))
    return GroundTruthFrame(file_path, lanes, visibility, categories)


def read_prediction(path: str | os.PathLike[str]) -> PredictionFrame:
    """Read and validate one prediction JSON."""
    data = load_json_object(path)
    file_path = require(data, "file_path", path)
    if not isinstance(file_path, str):
        raise OpenLaneFormatError(path, "'file_path' must be a string")
    lanes, categories = [], []
    for i, lane in enumerate(require_list(data, "lane_lines", path)):
        where = f"lane_lines[{i}]"
        xyz = numeric_array(require(lane, "xyz", path, where), (None, None), f"{where}.xyz", path)
        if xyz.shape[0] == 0 or xyz.shape[1] < 2:
            raise OpenLaneFormatError(
                path, f"{where}.xyz must be a non-empty (N, 3) or (N, 2) list, got {xyz.shape}"
            )
        lanes.append(xyz)
        categories.append(_category(lane, path, where, strict=False))
    return PredictionFrame(file_path, lanes, categories)


def read_test_list(path: str | os.PathLike[str]) -> list[str]:
    """Relative JSON paths named by a test list (one image or JSON path a line).

    As the official evaluator does, every 'jpg' in a line becomes 'json'. Blank lines are
    skipped (the official one crashes on them).
    """
    try:
        text = Path(path).read_text()
    except OSError as error:
        raise OpenLaneFormatError(path, f"cannot read the test list ({error.strerror})") from None
    return [line.replace("jpg", "json").lstrip("/") for line in text.splitlines() if line.strip()]


def _category(lane: dict[str, Any], path: str | os.PathLike[str], where: str, strict: bool) -> int:
    """A lane's category id.

    Predictions go through int() as in the official evaluator (3.0, "3" and 3.7 all read as
    3); ground-truth categories are compared as stored there, so they must be integral.
    """
    value = require(lane, "category", path, where)
    if strict:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value == int(value)
        ):
            raise OpenLaneFormatError(path, f"{where}.category must be an integer, got {value!r}")
        return int(value)
    try:
        return int(value)
    except (TypeError, ValueError, OverflowError):
        problem = f"{where}.category must be an integer, got {value!r}"
        raise OpenLaneFormatError(path, problem) from None
