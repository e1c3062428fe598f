"""Prediction files in OpenLane's JSON format, written during ``Trainer.predict``.

Layout under ``output_dir`` (what :func:`lanelab.metrics.openlane.evaluate` reads)::

    predictions/<clip_id>/<timestamp_ns>.json    every predicted frame
    ground_truth/<clip_id>/<timestamp_ns>.json   labeled frames (write_ground_truth)
    test_list.txt                                one "<clip_id>/<timestamp_ns>.jpg" per labeled frame

so that ``evaluate(output_dir / "ground_truth", output_dir / "predictions", output_dir /
"test_list.txt")`` scores them. The files are :mod:`lanelab.openlane.write`'s: predictions with
the points of visibility above the metric's threshold and each lane's score, ground truth with
its visible points.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import torch.distributed as dist
from lightning.pytorch.callbacks import BasePredictionWriter

from lanelab.lightning.predictions import PredictionBatch
from lanelab.openlane.lists import write_test_list
from lanelab.openlane.write import write_ground_truth, write_prediction

PREDICTIONS, GROUND_TRUTH, TEST_LIST = "predictions", "ground_truth", "test_list.txt"


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
        predictions = prediction.predictions
        for i, file_path in enumerate(prediction.file_paths):
            lanes = predictions.lanes(i, visible_only=False)  # write_prediction keeps the visible points
            scores = [lane.score for lane in lanes]
            write_prediction(self.output_dir / PREDICTIONS, file_path, lanes, predictions.threshold, scores)
            if self.write_ground_truth and prediction.labeled[i]:
                lanes = prediction.ground_truth.lanes(i, visible_only=True)
                K, T_lane_cam = (matrix[i].double().cpu().numpy() for matrix in (prediction.K, prediction.T_lane_cam))
                write_ground_truth(self.output_dir / GROUND_TRUTH, file_path, lanes, K, T_lane_cam)
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
            write_test_list(self.output_dir / TEST_LIST, lines)
