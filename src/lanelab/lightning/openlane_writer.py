"""Prediction files in OpenLane's JSON format, written during ``Trainer.predict``.

Layout under ``output_dir`` (what :func:`lanelab.metrics.openlane.evaluate` reads)::

    predictions/<clip_id>/<timestamp_ns>.json    every predicted frame
    ground_truth/<clip_id>/<timestamp_ns>.json   labeled frames (write_ground_truth)
    test_list.txt                                one "<clip_id>/<timestamp_ns>.jpg" per labeled frame

so that ``evaluate(output_dir / "ground_truth", output_dir / "predictions", output_dir /
"test_list.txt")`` scores them. A prediction file holds ``file_path`` and ``lane_lines``, each
with ``xyz`` (N, 3) in the lane frame (only the points of visibility above the metric's
threshold), ``visibility`` (N,), ``category`` and ``score``.

Ground-truth files follow OpenLane's layout (``xyz`` (3, N) in Waymo camera axes, x forward,
y left, z up; ``extrinsic`` maps them into the vehicle frame). The official evaluator keeps only
the camera height of the extrinsic's translation, putting the origin on the ground under the
camera; lanelab's metrics use the lane frame (DESIGN.md), so the files place the camera above
the lane-frame origin (true rotation and height) and the evaluator reads the lanes back in the
lane frame, where the in-loop metric scores them.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import numpy as np
import torch.distributed as dist
from lightning.pytorch.callbacks import BasePredictionWriter

from lanelab.atomic_file import atomic_output
from lanelab.lightning.predictions import Lane, PredictionBatch

PREDICTIONS, GROUND_TRUTH, TEST_LIST = "predictions", "ground_truth", "test_list.txt"

# Axis changes (signed permutations, so every product with them is exact): Waymo camera axes
# (x forward, y left, z up) from OpenCV camera axes (x right, y down, z forward), and vehicle
# axes (x forward, y left, z up) from lane axes (x right, y forward, z up).
_WAYMO_FROM_OPENCV = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_VEHICLE_FROM_LANE = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def prediction_json(file_path: str, lanes: Sequence[Lane]) -> dict[str, Any]:
    """A prediction file's content; lanes in the lane frame."""
    lane_lines = [
        {"xyz": lane.points.tolist(), "visibility": lane.visibility.tolist(), "category": lane.category,
         "score": lane.score}
        for lane in lanes
    ]  # fmt: skip
    return {"file_path": file_path, "lane_lines": lane_lines}


def ground_truth_json(file_path: str, lanes: Sequence[Lane], K: np.ndarray, T_lane_cam: np.ndarray) -> dict[str, Any]:
    """A ground-truth file's content for lanes in the lane frame, seen by a camera with
    intrinsics K (3, 3) and extrinsic T_lane_cam (4, 4) moved above the lane-frame origin."""
    R, height = T_lane_cam[:3, :3], T_lane_cam[2, 3]
    extrinsic = np.eye(4)
    extrinsic[:3, :3] = _VEHICLE_FROM_LANE @ R @ _WAYMO_FROM_OPENCV.T
    extrinsic[2, 3] = height
    lane_lines = []
    for lane in lanes:
        camera = R.T @ (lane.points - [0.0, 0.0, height]).T  # (3, P), OpenCV axes
        lane_lines.append({
            "xyz": (_WAYMO_FROM_OPENCV @ camera).tolist(),
            "visibility": lane.visibility.tolist(),
            "category": lane.category,
        })  # fmt: skip
    return {"file_path": file_path, "intrinsic": K.tolist(), "extrinsic": extrinsic.tolist(), "lane_lines": lane_lines}


def _write_json(path: Path, content: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(content))


class OpenLaneWriter(BasePredictionWriter):
    """Writes the :class:`PredictionBatch` of every predict step as OpenLane JSON files.

    output_dir: where the layout above goes; write_ground_truth: also the labeled frames'
    ground truth and the test list. Under DDP every rank writes its own frames and rank 0 the
    test list of all of them.
    """

    def __init__(self, output_dir: str | os.PathLike[str], write_ground_truth: bool) -> None:
        super().__init__(write_interval="batch")
        self.output_dir = Path(output_dir)
        self.write_ground_truth = write_ground_truth
        self._labeled: list[str] = []  # this rank's test-list lines

    def on_predict_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._labeled = []

    def write_on_batch_end(
        self,
        trainer: pl.Trainer,
        pl_module: pl.LightningModule,
        prediction: PredictionBatch,
        batch_indices: Sequence[int] | None,
        batch: Any,
        batch_idx: int,
        dataloader_idx: int,
    ) -> None:
        for i, file_path in enumerate(prediction.file_paths):
            name = Path(file_path).with_suffix(".json")
            lanes = prediction.predictions.lanes(i, visible_only=True)
            _write_json(self.output_dir / PREDICTIONS / name, prediction_json(file_path, lanes))
            if self.write_ground_truth and prediction.labeled[i]:
                lanes = prediction.ground_truth.lanes(i, visible_only=True)
                K, T_lane_cam = (matrix[i].double().cpu().numpy() for matrix in (prediction.K, prediction.T_lane_cam))
                _write_json(self.output_dir / GROUND_TRUTH / name, ground_truth_json(file_path, lanes, K, T_lane_cam))
                self._labeled.append(file_path)

    def on_predict_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if not self.write_ground_truth:
            return
        lines = self._labeled
        if dist.is_available() and dist.is_initialized():
            gathered: list[list[str]] = [[] for _ in range(dist.get_world_size())]
            dist.all_gather_object(gathered, lines)
            lines = [line for rank in gathered for line in rank]
        if trainer.is_global_zero:
            with atomic_output(self.output_dir / TEST_LIST) as tmp:
                tmp.write_text("".join(f"{line}\n" for line in lines))
