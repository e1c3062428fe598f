"""LaneDetectionModule: training, validation and prediction of any lane detector with Lightning,
through the detector contract of :mod:`lanelab.models.api` alone.

The batch decides how the detector runs (layout: :mod:`lanelab.models.api`):
- F > 1 frames (window sampler): windowed, ``net(batch)``; the loss and the metric look at
  the current (last) frame.
- F = 1 (stream sampler): streaming, StreamPETR-style, ``net.step(frame)`` with the batch's
  ``reset`` flags: the detector carries its streaming state from step to step. Every
  validation, test and prediction run starts from an empty state and leaves one behind, so
  training resumes after a mid-epoch validation as after a clip start.
Frames count towards the loss and the metric when the current frame is labeled and the sample
is not ``padding`` (:func:`~lanelab.models.api.scored_frames`).

The loss is the criterion's, called with the detector's outputs as they come and the batch;
every term it returns is logged. A loss of NaN or inf on any rank stops every rank before the optimiser step
(:class:`~lanelab.finite.NonFiniteError` naming the step and the batch's clips and frames), and
a checkpoint of NaN or inf weights is neither written nor read (naming the file). Hydra builds the module from ``conf/model/*.yaml`` (which
start from ``conf/module/lane_detection.yaml``); it holds no defaults of its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, TypedDict

import lightning.pytorch as pl
import torch
from torch import Tensor, nn
from torch.optim import Optimizer
from torch.optim.lr_scheduler import LRScheduler

from lanelab.finite import NonFiniteError
from lanelab.lightning.checkpoint import describe, non_finite_tensors
from lanelab.lightning.pictures import log_pictures, prediction_picture
from lanelab.lightning.predictions import (
    DenseLanes,
    PredictionBatch,
    ground_truth_lanes,
    predicted_lanes,
)
from lanelab.metrics.openlane import OpenLaneConfig
from lanelab.metrics.openlane_metric import OpenLaneMetric
from lanelab.models.api import FRAME_KEYS, DetectionOutputs, LaneCriterion, LaneDetector, scored_frames
from lanelab.models.parts.backbone import load_torchvision_weights
from lanelab.openlane.file_paths import store_file_path

BEST_VAL_F1_KEY = "lanelab_best_val_f1"  # the checkpoint's entry of LaneDetectionModule.best_val_f1


class Pictures(TypedDict):
    """model.pictures: what validation draws for the logger."""

    num_frames: int  # frames of the first validation batch drawn each validation (0: none)
    height: int  # pixels of each picture
    x_range: tuple[float, float]  # metres, lane frame: the region of the top views
    y_range: tuple[float, float]


class BackboneStart(TypedDict):
    """model.backbone: where the detector's backbone starts."""

    weights: str | None  # a torchvision-layout ResNet state dict file; None: from scratch


class LaneDetectionModule(pl.LightningModule):
    """net: the detector (:class:`~lanelab.models.api.LaneDetector`, an nn.Module); criterion:
    its loss (:class:`~lanelab.models.api.LaneCriterion`, an nn.Module); metric: the settings of
    the OpenLane metric of validation and test.

    optimizer: called with net, gives its optimiser (e.g. :func:`lanelab.lightning.optim.adamw`,
    which scales the lr by parameter name); scheduler: called with the optimiser and the run's
    number of optimiser steps, gives the lr schedule, stepped every step (e.g.
    :func:`lanelab.lightning.optim.warmup_cosine`). Both are Hydra partials (conf/optimizer,
    conf/scheduler).
    pictures: the validation pictures for the logger (:class:`Pictures`).
    nms_distance: metres; predicted lanes within this mean lateral distance (over the metric's
    close range) of a more confident one are dropped (models.parts.lane_nms); None: no NMS.
    backbone: {"weights": PATH or None}: a torchvision-layout ResNet state dict (e.g. ImageNet
    weights) loaded into ``net.backbone`` (a lanelab.models.parts.ResNet) when training starts; a
    resumed run's checkpoint, restored after it, overrides it, and evaluation from a checkpoint
    never reads it.
    """

    def __init__(
        self,
        net: LaneDetector,
        criterion: LaneCriterion,
        *,
        metric: OpenLaneConfig,
        optimizer: Callable[[nn.Module], Optimizer],
        scheduler: Callable[[Optimizer, int], LRScheduler],
        pictures: Pictures,
        nms_distance: float | None,
        backbone: BackboneStart,
    ) -> None:
        super().__init__()
        self.save_hyperparameters(ignore=["net", "criterion", "metric", "optimizer", "scheduler"])
        self.net, self.criterion = net, criterion
        self.metric_config = metric
        self.metrics = nn.ModuleDict({stage: OpenLaneMetric(metric) for stage in ("val", "test")})
        self.optimizer_factory, self.scheduler_factory = optimizer, scheduler
        self.pictures = pictures
        self.nms_distance = nms_distance
        self.backbone_weights = backbone["weights"]
        self.best_val_f1 = math.nan  # the best val/f1 of the run so far, kept in its checkpoints

    def setup(self, stage: str) -> None:
        # Before a resumed run's checkpoint is restored, which then overrides these weights.
        if stage == "fit" and self.backbone_weights is not None:
            load_torchvision_weights(self.net.backbone, self.backbone_weights)

    # ------------------------------------------------------------------ running
    def forward(self, batch: Mapping[str, Any]) -> DetectionOutputs:
        """The current frame's outputs (lanelab.models.api): windowed for F > 1, streaming for F = 1."""
        if batch["images"].shape[1] > 1:
            return self.net(batch)
        frame = {key: batch[key][:, -1] for key in FRAME_KEYS}
        return self.net.step({**frame, "reset": batch["reset"]})

    def _forget_stream(self) -> None:
        """Empty the streaming state of every stream (whatever the batch size was)."""
        self.net.reset(torch.ones(1, dtype=torch.bool, device=self.device))

    # Each evaluation run starts from an empty stream state (module doc).
    on_validation_start = on_validation_end = on_test_start = on_predict_start = _forget_stream

    def predictions(self, outputs: Mapping[str, Any], y: Tensor) -> DenseLanes:
        """The detector's lanes at longitudinal positions y (S,), with the metric's visibility
        threshold and the module's NMS, as validation, test and prediction see them."""
        nms = None if self.nms_distance is None else (self.nms_distance, self.metric_config.close_range)
        return predicted_lanes(self.net, outputs, y, self.metric_config.visibility_threshold, nms)

    def _predictions(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> DenseLanes:
        """Predicted lanes at the ground truth's y grid (the same for every sample)."""
        return self.predictions(outputs, batch["gt_y"][0])

    # ----------------------------------------------------------------- training
    def training_step(self, batch: Mapping[str, Any], batch_idx: int) -> Tensor:
        losses = self.criterion(self(batch), batch)
        finite = bool(torch.isfinite(losses["total"]))
        if not self._on_every_rank(finite):
            raise NonFiniteError(self._non_finite_loss(losses, batch) if not finite else (
                f"step {self.global_step}: the loss of another process is not finite; no optimiser step was taken"))
        count = int(scored_frames(batch).sum())
        if count:
            self.log("train/loss", losses["total"], batch_size=count, prog_bar=True)
            self.log_dict({f"train/loss_{term}": value for term, value in losses.items() if term != "total"},
                          batch_size=count)
        return losses["total"]

    def _on_every_rank(self, decision: bool) -> bool:
        """Whether decision holds on every rank. A rank that stopped alone would leave the others
        waiting in the gradient all-reduce."""
        return decision if self._trainer is None else self._trainer.strategy.reduce_boolean_decision(decision, all=True)

    def _non_finite_loss(self, losses: Mapping[str, Tensor], batch: Mapping[str, Any]) -> str:
        """The message of a NaN or inf loss: the step, the terms, the batch's current frames."""
        terms = ", ".join(f"{term}={float(value)}" for term, value in losses.items() if not torch.isfinite(value))
        frames = ", ".join(f"{clip}@{int(t)}" for clip, t in zip(batch["clip_id"], batch["timestamp_ns"][:, -1]))
        return (f"step {self.global_step}: the loss is not finite ({terms}) on the batch of frames "
                f"(clip_id@timestamp_ns) {frames}; no optimiser step was taken")

    # -------------------------------------------------------------- checkpoints
    def on_save_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        names = non_finite_tensors(checkpoint["state_dict"])
        if names:
            raise NonFiniteError(f"step {self.global_step}: not saving a checkpoint of NaN or inf weights "
                                 f"in {describe(names)}")
        checkpoint[BEST_VAL_F1_KEY] = self.best_val_f1

    def on_load_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        names = non_finite_tensors(checkpoint["state_dict"])
        if names:
            path = self._trainer.ckpt_path if self._trainer is not None else "the checkpoint"
            raise NonFiniteError(f"{path}: the checkpoint's weights hold NaN or inf in {describe(names)}")
        self.best_val_f1 = float(checkpoint.get(BEST_VAL_F1_KEY, math.nan))  # older checkpoints: none

    # --------------------------------------------------------------- evaluation
    def validation_step(self, batch: Mapping[str, Any], batch_idx: int) -> None:
        self._evaluate(batch, batch_idx, "val")

    def test_step(self, batch: Mapping[str, Any], batch_idx: int) -> None:
        self._evaluate(batch, batch_idx, "test")

    def on_validation_epoch_end(self) -> None:
        self._log_metric("val")

    def on_test_epoch_end(self) -> None:
        self._log_metric("test")

    def _evaluate(self, batch: Mapping[str, Any], batch_idx: int, stage: str) -> None:
        """Add the scored frames to the stage's metric; draw the first batch's."""
        outputs = self(batch)
        scored = scored_frames(batch)
        predictions, ground_truth = self._predictions(outputs, batch), ground_truth_lanes(batch)
        if scored.any():
            self.metrics[stage].update(predictions[scored].metric_input(), ground_truth[scored].metric_input())
        if stage == "val" and batch_idx == 0 and self.pictures["num_frames"] and not self.trainer.sanity_checking:
            self._log_pictures(batch, predictions, ground_truth, scored)

    def _log_metric(self, stage: str) -> None:
        """Log the metric of all ranks (the metric sums its states across ranks) and reset it;
        F1 on the progress bar, with the best validation F1 so far (``val/f1_best``)."""
        metric = self.metrics[stage]
        # The values are the same on every rank already; sync_dist says so to Lightning, which
        # would warn once per key under DDP otherwise (its all-reduce of equal values changes nothing).
        values = {f"{stage}/{key}": value.float() for key, value in metric.compute().items()}
        f1 = values.pop(f"{stage}/f1")
        self.log(f"{stage}/f1", f1, prog_bar=True, sync_dist=True)
        self.log_dict(values, sync_dist=True)
        metric.reset()
        if stage == "val" and not self.trainer.sanity_checking and math.isfinite(float(f1)):
            self.best_val_f1 = max(self.best_val_f1, float(f1)) if math.isfinite(self.best_val_f1) else float(f1)
            self.log("val/f1_best", self.best_val_f1, prog_bar=True, sync_dist=True)

    def _log_pictures(
        self, batch: Mapping[str, Any], predictions: DenseLanes, ground_truth: DenseLanes, scored: Tensor
    ) -> None:
        if not self.trainer.is_global_zero:
            return
        view = tuple(self.pictures["x_range"]), tuple(self.pictures["y_range"]), self.pictures["height"]
        pictures = []
        for b in scored.nonzero()[:, 0][: self.pictures["num_frames"]].tolist():
            lanes = predictions.lanes(b, visible_only=False), ground_truth.lanes(b, visible_only=True)
            camera = batch["images"][b, -1], batch["K"][b, -1], batch["T_lane_cam"][b, -1]
            title = f"{batch['clip_id'][b]} frame {int(batch['frame_index'][b, -1])}, step {self.global_step}"
            pictures.append(prediction_picture(*camera, *lanes, *view, title))
        log_pictures(self.trainer, "val/pictures", pictures)

    # --------------------------------------------------------------- prediction
    def predict_step(self, batch: Mapping[str, Any], batch_idx: int) -> PredictionBatch:
        """Dense lanes of the real frames of the batch (see :class:`PredictionBatch`)."""
        outputs = self(batch)
        real = ~batch["padding"]
        frames = [(clip, int(t), tags) for clip, t, tags, r in
                  zip(batch["clip_id"], batch["timestamp_ns"][:, -1], batch["tags"], real.tolist()) if r]  # fmt: skip
        return PredictionBatch(
            file_paths=[store_file_path(*frame) for frame in frames],
            clip_ids=[clip for clip, _, _ in frames],
            frame_indices=batch["frame_index"][real, -1],
            labeled=batch["labeled"][real, -1],
            predictions=self._predictions(outputs, batch)[real],
        )

    # ---------------------------------------------------------------- optimiser
    def configure_optimizers(self) -> dict[str, Any]:
        optimizer = self.optimizer_factory(self.net)
        scheduler = self.scheduler_factory(optimizer, int(self.trainer.estimated_stepping_batches))
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}
