"""ONCE-3DLanes label and prediction files, read with errors that name the file, and written.

A label (``<split>/<sequence>/cam01/<stamp>.json``)::

    {"lanes": [[[x, y, z], ...], ...], "calibration": [[fx, 0, cx, 0], [0, fy, cy, 0], [0, 0, 1, 0]]}

lanes in the camera frame (x right, y down, z forward, metres); ``calibration`` (3, 4) the
projection matrix ``[K | 0]``. A prediction file, at the same relative path::

    {"lanes": [{"points": [[x, y, z], ...], "score": s}, ...]}

as the official ``eval.py`` reads them (once-3dlanes/once_3dlanes_benchmark). The writers write
these contents atomically with :func:`lanelab.openlane.write.write_json`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from lanelab.geometry.intrinsics import TOLERANCE, pinhole_problem
from lanelab.json_files import LaneFileError, load_json_object, numeric_array, require, require_list


@dataclass(frozen=True)
class OnceLabel:
    """One label file: calibration (3, 4) ``[K | 0]``; lanes, each (P, 3) camera frame, P >= 2."""

    calibration: np.ndarray
    lanes: list[np.ndarray]

    @property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsics: the calibration's left 3 x 3."""
        return self.calibration[:, :3].copy()


def lane_arrays(data: dict[str, Any], path: str | os.PathLike[str]) -> list[np.ndarray]:
    """The ``lanes`` of a label's content, each (P, 3); lanes of fewer than 2 points left out,
    as the official evaluator does."""
    lanes = []
    for i, lane in enumerate(require_list(data, "lanes", path)):
        if isinstance(lane, list) and len(lane) < 2:
            continue
        lanes.append(numeric_array(lane, (None, 3), f"lanes[{i}]", path))
    return lanes


def read_label(path: str | os.PathLike[str]) -> OnceLabel:
    """Read and validate a label for ingestion: a pinhole ``[K | 0]`` calibration, finite lane
    points, every point in front of the camera (z > 0). LaneFileError names the file and fault."""
    data = load_json_object(path)
    calibration = numeric_array(require(data, "calibration", path), (3, 4), "'calibration'", path)
    if not np.isfinite(calibration).all():
        raise LaneFileError(path, "'calibration' holds NaN or inf")
    problem = pinhole_problem(calibration[:, :3])
    if problem:
        raise LaneFileError(path, f"'calibration''s left 3x3 is not a pinhole matrix: {problem}")
    if np.abs(calibration[:, 3]).max() > TOLERANCE:  # K alone would project these points elsewhere
        raise LaneFileError(path, f"'calibration''s last column is {calibration[:, 3].tolist()}, not 0 ([K | 0])")
    lanes = lane_arrays(data, path)
    for i, lane in enumerate(lanes):
        if not np.isfinite(lane).all():
            raise LaneFileError(path, f"a lane ({i} of those with 2 or more points) holds NaN or inf")
        if (lane[:, 2] <= 0).any():
            raise LaneFileError(path, f"a lane ({i} of those with 2 or more points) has points behind the camera "
                                      f"(z <= 0: {lane[:, 2].min():g} m)")  # fmt: skip
    return OnceLabel(calibration, lanes)


def label_json(lanes: Sequence[np.ndarray], K: np.ndarray) -> dict[str, Any]:
    """A label file's content: lanes (P, 3) in the camera frame, calibration ``[K | 0]`` (K (3, 3))."""
    calibration = np.zeros((3, 4))
    calibration[:, :3] = K
    return {"lanes": [np.asarray(lane, np.float64).tolist() for lane in lanes], "calibration": calibration.tolist()}


def prediction_json(lanes: Sequence[np.ndarray], scores: Sequence[float]) -> dict[str, Any]:
    """A prediction file's content: lanes (P, 3) in the camera frame, one score each."""
    return {"lanes": [{"points": np.asarray(lane, np.float64).tolist(), "score": float(score)}
                      for lane, score in zip(lanes, scores)]}  # fmt: skip

