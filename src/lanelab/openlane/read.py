"""Reading and validating OpenLane 3D-lane JSON files (ground truth and predictions).

The layout is the one of the official evaluator (OpenDriveLab/OpenLane,
``eval/LANE_evaluation/lane3d/eval_3D_lane.py``):

- a ground-truth file has ``file_path``, ``extrinsic`` (4, 4), ``intrinsic`` (3, 3) and
  ``lane_lines``, each lane with ``xyz`` (3, N) in the camera frame, ``visibility`` (N,),
  ``category`` and, not always, ``track_id``; the reader converts the lanes into the
  evaluator's ground frame (:mod:`lanelab.openlane.ground_frame`);
- a prediction file has ``file_path`` and ``lane_lines``, each lane with ``xyz`` (N, 3) in the
  evaluator's ground frame (x right, y forward, z up) and ``category``; as in the official
  evaluator, N x 2 lanes get z = 0 and columns past the third are ignored. Any other key
  (``visibility``, scores...) is ignored.

Every problem is reported as an :class:`OpenLaneFormatError` that names the file, NaN or
infinity (which Python's JSON reads) in any number included: a lane is never silently dropped.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from lanelab.json_files import LaneFileError, load_json_object, numeric_array, require, require_list
from lanelab.openlane.ground_frame import camera_lane_to_ground, ground_from_camera

# The error every OpenLane reader raises (the name users of evaluate() catch).
OpenLaneFormatError = LaneFileError


@dataclass(frozen=True)
class GroundTruthFrame:
    """One ground-truth frame, lanes already in the evaluator's ground frame.

    lanes[i]: (N_i, 3) points (x right, y forward, z up), visibility[i]: (N_i,),
    categories[i]: OpenLane category id. K: (3, 3) intrinsics; T_ground_cam: (4, 4) the
    OpenCV camera in the ground frame (:func:`~lanelab.openlane.ground_frame.ground_from_camera`).
    """

    file_path: str
    lanes: list[np.ndarray]
    visibility: list[np.ndarray]
    categories: list[int]
    K: np.ndarray
    T_ground_cam: np.ndarray


@dataclass(frozen=True)
class PredictionFrame:
    """One prediction frame: lanes[i] is (N_i, 3) (or (N_i, 2): z = 0) in the ground frame."""

    file_path: str
    lanes: list[np.ndarray]
    categories: list[int]


def read_camera_header(path: str | os.PathLike[str]) -> tuple[dict[str, Any], str, np.ndarray, np.ndarray]:
    """The part every annotated OpenLane file shares (ground truth, the dataset's own annotations):
    the JSON object, its ``file_path``, intrinsic K (3, 3) and extrinsic (4, 4), validated and finite."""
    data = load_json_object(path)
    file_path = require(data, "file_path", path)
    if not isinstance(file_path, str):
        raise OpenLaneFormatError(path, "'file_path' must be a string")
    extrinsic = finite(numeric_array(require(data, "extrinsic", path), (4, 4), "'extrinsic'", path), "'extrinsic'", path)
    K = finite(numeric_array(require(data, "intrinsic", path), (3, 3), "'intrinsic'", path), "'intrinsic'", path)
    return data, file_path, K, extrinsic


def read_ground_truth(path: str | os.PathLike[str]) -> GroundTruthFrame:
    """Read and validate one ground-truth JSON and convert its lanes to the ground frame."""
    data, file_path, K, extrinsic = read_camera_header(path)
    T = ground_from_camera(extrinsic)

    lanes, visibility, categories = [], [], []
    for i, lane in enumerate(require_list(data, "lane_lines", path)):
        where = f"lane_lines[{i}]"
        xyz = numeric_array(require(lane, "xyz", path, where), (3, None), f"{where}.xyz", path)
        vis = numeric_array(
            require(lane, "visibility", path, where), (None,), f"{where}.visibility", path
        )
        finite(xyz, f"{where}.xyz", path)
        finite(vis, f"{where}.visibility", path)
        if vis.shape[0] != xyz.shape[1]:
            raise OpenLaneFormatError(
                path, f"{where}: {vis.shape[0]} visibility values for {xyz.shape[1]} points"
            )
        lanes.append(camera_lane_to_ground(xyz, T))
        visibility.append(vis)
        categories.append(_category(lane, path, where, strict=True))
    return GroundTruthFrame(file_path, lanes, visibility, categories, K, T)


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
        finite(xyz[:, :3], f"{where}.xyz", path)  # the columns the evaluator reads
        lanes.append(xyz)
        categories.append(_category(lane, path, where, strict=False))
    return PredictionFrame(file_path, lanes, categories)


def finite(array: np.ndarray, what: str, path: str | os.PathLike[str]) -> np.ndarray:
    """array, unless it holds NaN or infinity (then OpenLaneFormatError naming the file and ``what``)."""
    if not np.isfinite(array).all():
        raise OpenLaneFormatError(path, f"{what} holds NaN or infinity")
    return array


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
