"""Predictions (dense lanes in an OpenLane store's lane frame) -> OpenLane prediction files.

The lane frame of a store made by ``lanelab-openlane`` is the official evaluator's ground
frame (:mod:`data_ingest.openlane.annotation`), so predicted points go into the file as
they are. A file reads::

    {"file_path": "<the ground truth's file_path>",
     "lane_lines": [{"xyz": [[x, y, z], ...], "category": 1, "visibility": [...]}, ...]}

and lies at ``<pred_dir>/<file_path with .json>``, where ``lanelab-eval`` and the official
evaluator look for it (a test-list line, "jpg" -> "json"). The evaluator takes every point
of a predicted lane as part of it, so only points with visibility above the threshold
(:attr:`OpenLaneConfig.visibility_threshold`) are written, and a lane left with fewer than
two is left out; ``visibility`` keeps the written points' values for other tools.
"""

from __future__ import annotations

import json
import os
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from data_ingest.openlane.adapter import FILE_PATH_TAG
from lanelab.metrics.openlane import OpenLaneConfig
from lanelab.store import FrameRecord

if TYPE_CHECKING:
    from lanelab.viz.lanes import LaneLike  # points (P, 3), visibility (P,), category

VISIBILITY_THRESHOLD = OpenLaneConfig().visibility_threshold


def file_path_of(frame: FrameRecord) -> str:
    """The OpenLane ``file_path`` of a frame of an OpenLane store (its ``openlane.file_path`` tag)."""
    try:
        return frame.tags[FILE_PATH_TAG]
    except KeyError:
        raise KeyError(f"frame at {frame.timestamp_ns} ns has no {FILE_PATH_TAG!r} tag: "
                       "not from a store made by lanelab-openlane") from None


def prediction_json(
    file_path: str, lanes: Sequence[LaneLike], visibility_threshold: float = VISIBILITY_THRESHOLD
) -> dict[str, Any]:
    """The prediction file's content for one frame; lanes' points (P, 3) in the lane frame."""
    lane_lines = []
    for lane in lanes:
        visibility = np.asarray(lane.visibility, dtype=np.float64)
        keep = visibility > visibility_threshold
        if np.count_nonzero(keep) < 2:
            continue
        lane_lines.append({
            "xyz": np.asarray(lane.points, dtype=np.float64)[keep].tolist(),
            "category": int(lane.category),
            "visibility": visibility[keep].tolist(),
        })
    return {"file_path": file_path, "lane_lines": lane_lines}


def prediction_path(pred_dir: str | os.PathLike[str], file_path: str) -> Path:
    """Where the prediction of the frame with this ``file_path`` goes."""
    return Path(pred_dir) / PurePosixPath(file_path).with_suffix(".json")


def write_prediction(
    pred_dir: str | os.PathLike[str],
    file_path: str,
    lanes: Sequence[LaneLike],
    visibility_threshold: float = VISIBILITY_THRESHOLD,
) -> Path:
    """Write one frame's prediction file; its path.

    A plain write, not an atomic one: a run writes tens of thousands of these, and a torn
    file fails the evaluation with a message naming it.
    """
    path = prediction_path(pred_dir, file_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(prediction_json(file_path, lanes, visibility_threshold)))
    return path
