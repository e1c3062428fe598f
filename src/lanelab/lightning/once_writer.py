"""Prediction files in ONCE-3DLanes' layout and JSON, written during ``Trainer.predict``.

Layout under ``output_dir`` (what :func:`lanelab.metrics.once.evaluate_once` and the official
``eval.py`` read)::

    predictions/<sequence>/cam01/<stamp>.json    every predicted frame
    ground_truth/<sequence>/cam01/<stamp>.json   labeled frames

at each frame's label path (:func:`lanelab.once.file_paths.store_label_path`: a ``lanelab-once``
store's own). Lanes are written in the frame's camera frame (:mod:`lanelab.once.write`):
predictions with the points of visibility above the metric's threshold and each lane's score,
ground truth as the store holds it. The frame is read from the store for its ``T_lane_cam`` and
tags, so a store is required. Bad paths stop the run as :class:`~lanelab.lightning.OpenLaneWriter`'s do.
"""

from __future__ import annotations

import lightning.pytorch as pl

from lanelab.lightning.openlane_writer import GROUND_TRUTH, PREDICTIONS, OpenLaneWriter
from lanelab.lightning.predictions import PredictionBatch
from lanelab.once.write import write_ground_truth, write_prediction


class OnceWriter(OpenLaneWriter):
    """Writes the :class:`PredictionBatch` of every predict step as ONCE-3DLanes JSON files, with the
    ground truth of the labeled frames of the store ``ground_truth``; no test list (the ONCE metric
    scores every label)."""

    def _write_frame(self, prediction: PredictionBatch, i: int) -> None:
        clip_id, index = prediction.clip_ids[i], int(prediction.frame_indices[i])
        (frame,) = self.store.read_frames(clip_id, index, index + 1)
        write_prediction(self.output_dir / PREDICTIONS, clip_id, frame, prediction.predictions.lanes(i, visible_only=True))
        if prediction.labeled[i]:
            write_ground_truth(self.output_dir / GROUND_TRUTH, clip_id, frame)

    def on_predict_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        """Nothing to gather: no test list."""
