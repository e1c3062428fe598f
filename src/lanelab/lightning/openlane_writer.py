"""Prediction files in OpenLane's JSON format, written during ``Trainer.predict``.

Layout under ``output_dir`` (what :func:`lanelab.metrics.openlane.evaluate` reads)::

    predictions/<file_path>.json    every predicted frame
    ground_truth/<file_path>.json   labeled frames (with a ground-truth store)
    test_list.txt                   the labeled frames' file_path, one a line

where a frame's ``file_path`` is "<clip_id>/<timestamp_ns>.jpg", or for a store made by
``lanelab-openlane`` the frame's own OpenLane ``file_path`` (``validation/segment-x/<stamp>.jpg``,
:func:`lanelab.openlane.file_paths.store_file_path`), so that the files line up with the official
tree and its images. ``evaluate(output_dir / "ground_truth", output_dir / "predictions",
output_dir / "test_list.txt")`` scores them. The files are :mod:`lanelab.openlane.write`'s:
predictions with the points of visibility above the metric's threshold and each lane's score;
ground truth as the store holds it (every point with its visibility, the camera's own K and
extrinsic; :func:`~lanelab.openlane.lane_order.source_order`), not the model's resampled
targets, so that an OpenLane store's files give back its source annotations point for point.

A ``file_path`` comes from the store's data: one that would put a file outside its folder
(absolute, or with ``..``) stops the run with a :class:`~lanelab.store.ClipFileError` naming
the clip, the frame and the value; the files already written stay.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import torch.distributed as dist
from lightning.pytorch.callbacks import BasePredictionWriter

from lanelab.data_paths import UnsafePathError
from lanelab.lightning.predictions import PredictionBatch
from lanelab.openlane.lane_order import source_order
from lanelab.openlane.lists import write_test_list
from lanelab.openlane.write import write_ground_truth, write_prediction
from lanelab.store import ClipFileError, ClipStore

PREDICTIONS, GROUND_TRUTH, TEST_LIST = "predictions", "ground_truth", "test_list.txt"


class OpenLaneWriter(BasePredictionWriter):
    """Writes the :class:`PredictionBatch` of every predict step as OpenLane JSON files.

    output_dir: where the layout above goes; ground_truth: the clip store predicted, whose
    labeled frames' ground truth and test list are written too (None: predictions alone).
    Under DDP every rank writes its own frames and rank 0 the test list of all of them.
    """

    def __init__(self, output_dir: str | os.PathLike[str], ground_truth: str | os.PathLike[str] | None) -> None:
        super().__init__(write_interval="batch")
        self.output_dir = Path(output_dir)
        self.store = None if ground_truth is None else ClipStore(ground_truth)
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
        for i in range(len(prediction.file_paths)):
            try:
                self._write_frame(prediction, i)
            except UnsafePathError as err:
                clip_id, index = prediction.clip_ids[i], int(prediction.frame_indices[i])
                where = self.store.clip_path(clip_id) if self.store is not None else f"clip {clip_id}"
                raise ClipFileError(f"{where}: frame {index}: {err}") from None

    def _write_frame(self, prediction: PredictionBatch, i: int) -> None:
        """The prediction file of frame i of the batch, and its ground truth if labeled."""
        predictions, file_path = prediction.predictions, prediction.file_paths[i]
        lanes = predictions.lanes(i, visible_only=False)  # write_prediction keeps the visible points
        scores = [lane.score for lane in lanes]
        write_prediction(self.output_dir / PREDICTIONS, file_path, lanes, predictions.threshold, scores)
        if self.store is not None and prediction.labeled[i]:
            index = int(prediction.frame_indices[i])
            (frame,) = self.store.read_frames(prediction.clip_ids[i], index, index + 1)
            lanes = source_order(frame.lanes, frame.tags)
            write_ground_truth(self.output_dir / GROUND_TRUTH, file_path, lanes, frame.K, frame.T_lane_cam)
            self._labeled.append(file_path)

    def on_predict_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if self.store is None:
            return
        lines = self._labeled
        if dist.is_available() and dist.is_initialized():
            gathered: list[list[str]] = [[] for _ in range(dist.get_world_size())]
            dist.all_gather_object(gathered, lines)
            lines = [line for rank in gathered for line in rank]
        if trainer.is_global_zero:
            write_test_list(self.output_dir / TEST_LIST, lines)
