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

The ONCE metric (and ``eval.py``) scores every label under ``ground_truth/``, with no test list, so
at the end of the epoch the files an earlier evaluation into the same folder left there (another
split, another store) are removed, on rank zero once every rank's frames are gathered: both
folders then hold exactly the frames of this run.
"""

from __future__ import annotations

from pathlib import Path

import lightning.pytorch as pl
import torch.distributed as dist

from lanelab.lightning.openlane_writer import GROUND_TRUTH, PREDICTIONS, OpenLaneWriter
from lanelab.lightning.predictions import PredictionBatch
from lanelab.once.write import write_ground_truth, write_prediction


class OnceWriter(OpenLaneWriter):
    """Writes the :class:`PredictionBatch` of every predict step as ONCE-3DLanes JSON files, with the
    ground truth of the labeled frames of the store ``ground_truth``; no test list (the ONCE metric
    scores every label), so files of earlier evaluations into the folder are removed at the end."""

    def on_predict_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._predicted: list[str] = []  # this rank's frames, by relative label path
        self._labeled = []  # those with ground truth

    def _write_frame(self, prediction: PredictionBatch, i: int) -> None:
        clip_id, index = prediction.clip_ids[i], int(prediction.frame_indices[i])
        (frame,) = self.store.read_frames(clip_id, index, index + 1)
        lanes = prediction.predictions.lanes(i, visible_only=True)
        path = write_prediction(self.output_dir / PREDICTIONS, clip_id, frame, lanes)
        self._predicted.append(path.relative_to(self.output_dir / PREDICTIONS).as_posix())
        if prediction.labeled[i]:
            path = write_ground_truth(self.output_dir / GROUND_TRUTH, clip_id, frame)
            self._labeled.append(path.relative_to(self.output_dir / GROUND_TRUTH).as_posix())

    def on_predict_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        """Every rank's frames gathered; on rank zero, the files no rank wrote removed."""
        written = (self._predicted, self._labeled)
        if dist.is_available() and dist.is_initialized():
            gathered: list[tuple[list[str], list[str]]] = [([], []) for _ in range(dist.get_world_size())]
            dist.all_gather_object(gathered, written)
            written = ([p for rank in gathered for p in rank[0]], [p for rank in gathered for p in rank[1]])
        if trainer.is_global_zero:
            for folder, frames in zip((PREDICTIONS, GROUND_TRUTH), written):
                remove_other_files(self.output_dir / folder, set(frames))


def remove_other_files(folder: Path, keep: set[str]) -> list[Path]:
    """Remove the ``*.json`` files below folder whose relative path (posix) is not in keep, and the
    folders that leaves empty; the files removed."""
    removed = [path for path in sorted(folder.rglob("*.json")) if path.relative_to(folder).as_posix() not in keep]
    for path in removed:
        path.unlink()
    emptied = {directory for path in removed for directory in path.parents if folder in directory.parents}
    for directory in sorted(emptied, key=lambda d: len(d.parts), reverse=True):  # the deepest first
        if not any(directory.iterdir()):
            directory.rmdir()
    return removed
