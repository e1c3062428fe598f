"""Writing OpenLane JSON files of lanes in the lane frame: predictions and ground truth.

A prediction file reads::

    {"file_path": "<the frame's file_path>",
     "lane_lines": [{"xyz": [[x, y, z], ...], "visibility": [...], "category": 1, "score": 0.9}, ...]}

with ``xyz`` (N, 3) in the lane frame (``score`` only where the lanes have scores). The
evaluator takes every point of a predicted lane as part of it, so only points with visibility
above a threshold (:data:`VISIBILITY_THRESHOLD` unless told) are written, and a lane left with
fewer than two is left out; ``visibility`` keeps the written points' values for other tools.
The lane frame of a store made by ``lanelab-openlane`` is the evaluator's ground frame, so
lanes predicted there are written unchanged and score as officially.

Ground-truth files follow OpenLane's layout (``xyz`` (3, N) in Waymo camera axes, x forward,
y left, z up; ``extrinsic`` maps them into the vehicle frame). The official evaluator keeps only
the camera height of the extrinsic's translation, putting the origin on the ground under the
camera; lanelab's metrics use the lane frame (DESIGN.md), so the files place the camera above
the lane-frame origin (true rotation and height, :mod:`lanelab.openlane.ground_frame`) and the
evaluator reads the lanes back in the lane frame.

A frame's file lies at its ``file_path`` with .json (:func:`~lanelab.openlane.file_paths.json_path`),
where ``lanelab-eval`` and the official evaluator look for it, and is written atomically.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from lanelab.atomic_file import atomic_output
from lanelab.lanes import Lane
from lanelab.openlane.file_paths import json_path
from lanelab.openlane.ground_frame import extrinsic_above_origin, lane_to_camera

# Predicted points of visibility at or below this are not part of their lane; 0.5, as the
# visibility of lanelab's training targets (lanelab.data.targets). The default of the OpenLane
# metric's visibility_threshold (lanelab.metrics.OpenLaneConfig).
VISIBILITY_THRESHOLD = 0.5


def prediction_json(
    file_path: str,
    lanes: Sequence[Lane],
    visibility_threshold: float = VISIBILITY_THRESHOLD,
    scores: Sequence[float] | None = None,
) -> dict[str, Any]:
    """A prediction file's content; lanes' points (P, 3) in the lane frame, scores (one a
    lane) written where given."""
    lane_lines = []
    for i, lane in enumerate(lanes):
        visibility = np.asarray(lane.visibility, dtype=np.float64)
        keep = visibility > visibility_threshold
        if np.count_nonzero(keep) < 2:
            continue
        line = {
            "xyz": np.asarray(lane.points, dtype=np.float64)[keep].tolist(),
            "visibility": visibility[keep].tolist(),
            "category": int(lane.category),
        }
        if scores is not None:
            line["score"] = float(scores[i])
        lane_lines.append(line)
    return {"file_path": file_path, "lane_lines": lane_lines}


def ground_truth_json(file_path: str, lanes: Sequence[Lane], K: np.ndarray, T_lane_cam: np.ndarray) -> dict[str, Any]:
    """A ground-truth file's content for lanes (every point written) in the lane frame, seen
    by a camera with intrinsics K (3, 3) and extrinsic T_lane_cam (4, 4) moved above the
    lane-frame origin."""
    lane_lines = [
        {"xyz": lane_to_camera(lane.points, T_lane_cam).tolist(), "visibility": lane.visibility.tolist(),
         "category": lane.category}
        for lane in lanes
    ]  # fmt: skip
    return {"file_path": file_path, "intrinsic": K.tolist(), "extrinsic": extrinsic_above_origin(T_lane_cam).tolist(),
            "lane_lines": lane_lines}  # fmt: skip


def write_json(path: str | os.PathLike[str], content: dict[str, Any]) -> None:
    """Write an OpenLane JSON file atomically, making its folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(content))


def write_prediction(
    pred_dir: str | os.PathLike[str],
    file_path: str,
    lanes: Sequence[Lane],
    visibility_threshold: float = VISIBILITY_THRESHOLD,
    scores: Sequence[float] | None = None,
) -> Path:
    """Write one frame's prediction file (:func:`prediction_json`) under pred_dir; its path."""
    path = json_path(pred_dir, file_path)
    write_json(path, prediction_json(file_path, lanes, visibility_threshold, scores))
    return path


def write_ground_truth(
    gt_dir: str | os.PathLike[str], file_path: str, lanes: Sequence[Lane], K: np.ndarray, T_lane_cam: np.ndarray
) -> Path:
    """Write one frame's ground-truth file (:func:`ground_truth_json`) under gt_dir; its path."""
    path = json_path(gt_dir, file_path)
    write_json(path, ground_truth_json(file_path, lanes, K, T_lane_cam))
    return path
