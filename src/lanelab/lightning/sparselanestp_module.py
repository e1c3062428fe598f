"""SparseLaneSTPModule: training, validation and prediction of SparseLaneSTP (and of its
single-frame LATR-like baseline, the same code configured differently) with Lightning.

The batch decides how the model runs (layout: :mod:`lanelab.data.dataset`):
- F > 1 frames (window sampler): windowed. The F frames are unrolled through a fresh memory
  queue, oldest first; the loss and the metric look at the current (last) frame.
- F = 1 (stream sampler): streaming, StreamPETR-style. The model's memory queue carries over
  from step to step and is emptied where ``batch["reset"]`` says a stream starts a clip; its
  contents are detached, so gradients stay within the current frame. Every validation, test
  and prediction run starts from an empty memory and leaves one behind, so training resumes
  after a mid-epoch validation as after a clip start.
Frames count towards the loss and the metric when the current frame is labeled and the sample
is not ``padding`` (a repeat the samplers add to fill batches).

The loss is the criterion's (:class:`lanelab.models.losses.SparseLaneSTPLoss`: detection
losses with deep supervision over all decoder layers, spatial priors, the temporal regulariser
of eq. 12-13) plus the query generator's auxiliary instance-mask loss
(:class:`lanelab.models.losses.InstanceMaskLoss`), which pairs each line's mask with the lane the
detection loss gave that line (as LATR trains both on one assignment); this module only adapts
the model's stacked outputs to their inputs (:func:`criterion_inputs`). Hydra builds the module from
``conf/model/*.yaml``; it holds no defaults of its own.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any, TypedDict

import lightning.pytorch as pl
import torch
from torch import Tensor, nn

from lanelab.lightning.optim import parameter_groups, warmup_cosine
from lanelab.lightning.pictures import log_pictures, prediction_picture
from lanelab.lightning.predictions import (
    DenseLanes,
    PredictionBatch,
    ground_truth_lanes,
    predicted_lanes,
)
from lanelab.metrics.openlane import OpenLaneConfig
from lanelab.metrics.openlane_metric import OpenLaneMetric
from lanelab.models.backbone import load_torchvision_weights
from lanelab.models.losses import InstanceMaskLoss, SparseLaneSTPLoss
from lanelab.models.memory_queue import MemoryState
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.openlane.file_paths import frame_path

FRAME_KEYS = ("images", "K", "T_lane_cam", "T_world_lane")
TARGET_KEYS = ("gt_y", "gt_x", "gt_z", "gt_vis", "gt_category", "gt_mask")


def criterion_inputs(outputs: Mapping[str, Any], frames: Tensor) -> dict[str, Any]:
    """The criterion's input for the batch elements selected by frames (B,) bool: every
    decoder layer's control points (B', N, M, 4) and logits (B', N, K + 1), and for the
    temporal regulariser the last layer's points with the memory the frame attended to; the
    lines' anchors (the matcher's, when it matches on anchors)."""
    points, logits = outputs["points"][:, frames], outputs["logits"][:, frames]
    memory = outputs["memory"]
    if memory is not None:
        memory = MemoryState(**{field.name: getattr(memory, field.name)[frames] for field in fields(MemoryState)})
    return {
        "layers": [{"control_points": p, "logits": c} for p, c in zip(points, logits)],
        "temporal": {"current": points[-1], "propagated_memory": memory},
        "anchors": outputs.get("anchors"),
    }


class BackboneStart(TypedDict):
    """model.backbone: where the backbone starts (its shape is the model/backbone group's)."""

    weights: str | None  # a torchvision-layout ResNet state dict file; None: from scratch


class SparseLaneSTPModule(pl.LightningModule):
    """net: the SparseLaneSTP; criterion: its SparseLaneSTPLoss; mask_criterion: the auxiliary
    InstanceMaskLoss of its query generator; metric: the settings (fields of
    :class:`~lanelab.metrics.OpenLaneConfig`) of the OpenLane metric of validation and test.

    Optimiser (LATR's, see :mod:`lanelab.lightning.optim`): AdamW with lr, weight_decay, betas;
    lr_multipliers {parameter-name key: factor} (e.g. backbone, sampling_offsets); a linear
    warm-up over warmup_steps, then a cosine to min_lr at the end of training.
    num_pictures: frames of the first validation batch drawn and logged each validation.
    backbone: {"weights": PATH or None}: a torchvision-layout ResNet state dict (e.g. ImageNet
    weights) loaded into the backbone when training starts; a resumed run's checkpoint, restored
    after it, overrides it, and evaluation from a checkpoint never reads it.
    nms_distance: metres; predicted lanes within this mean lateral distance (over the metric's
    close range) of a more confident one are dropped (models.lane_nms); None: no NMS.
    """

    def __init__(
        self,
        net: SparseLaneSTP,
        criterion: SparseLaneSTPLoss,
        mask_criterion: InstanceMaskLoss,
        *,
        metric: Mapping[str, Any],
        lr: float,
        weight_decay: float,
        betas: Sequence[float],
        lr_multipliers: Mapping[str, float],
        warmup_steps: int,
        min_lr: float,
        num_pictures: int,
        backbone: BackboneStart | None = None,
        nms_distance: float | None = None,
    ) -> None:
        super().__init__()
        self.save_hyperparameters(ignore=["net", "criterion", "mask_criterion"])
        self.net = net
        self.criterion, self.mask_criterion = criterion, mask_criterion
        self.metric_config = OpenLaneConfig(**metric)
        self.metrics = nn.ModuleDict({stage: OpenLaneMetric(self.metric_config) for stage in ("val", "test")})
        self.lr, self.weight_decay, self.betas = lr, weight_decay, tuple(betas)
        self.lr_multipliers = dict(lr_multipliers)
        self.warmup_steps, self.min_lr = warmup_steps, min_lr
        self.num_pictures = num_pictures
        self.backbone_weights = (backbone or {}).get("weights")
        self.nms_distance = nms_distance

    def setup(self, stage: str) -> None:
        # Before a resumed run's checkpoint is restored, which then overrides these weights.
        if stage == "fit" and self.backbone_weights is not None:
            load_torchvision_weights(self.net.backbone, self.backbone_weights)

    # ------------------------------------------------------------------ running
    def forward(self, batch: Mapping[str, Any]) -> dict[str, Any]:
        """The current frame's outputs (see ``SparseLaneSTP.step``): windowed for F > 1,
        streaming for F = 1."""
        if batch["images"].shape[1] > 1:
            return self.net(batch)
        frame = {key: batch[key][:, -1] for key in FRAME_KEYS}
        return self.net.step({**frame, "reset": batch["reset"]})

    def _forget_stream(self) -> None:
        """Empty the streaming memory of every stream (whatever the batch size was)."""
        self.net.reset(torch.ones(1, dtype=torch.bool, device=self.device))

    # Each evaluation run starts from an empty stream memory and leaves one behind (module doc).
    on_validation_start = on_validation_end = on_test_start = on_predict_start = _forget_stream

    @staticmethod
    def _scored(batch: Mapping[str, Any]) -> Tensor:
        """(B,) bool: the frames that count (current frame labeled, not padding)."""
        return batch["labeled"][:, -1] & ~batch["padding"]

    def _predictions(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> DenseLanes:
        """Predicted lanes at the ground truth's y grid (the same for every sample)."""
        nms = None if self.nms_distance is None else (self.nms_distance, self.metric_config.close_range)
        return predicted_lanes(self.net, outputs, batch["gt_y"][0], self.metric_config.visibility_threshold, nms)

    # ----------------------------------------------------------------- training
    def training_step(self, batch: Mapping[str, Any], batch_idx: int) -> Tensor:
        outputs = self(batch)
        scored = self._scored(batch)
        count = int(scored.sum())
        if count == 0:
            # Nothing to learn from; a zero that reaches the outputs keeps DDP ranks in step.
            return sum(outputs[key].sum() * 0.0 for key in ("points", "logits", "masks"))
        targets = {key: batch[key][scored] for key in TARGET_KEYS}
        losses = self.criterion(criterion_inputs(outputs, scored), targets)
        camera = batch["K"][scored, -1], batch["T_lane_cam"][scored, -1]
        # Each line's instance mask is the lane its control points are trained on (LATR pairs both alike).
        masks = self.mask_criterion(
            outputs["masks"][scored], targets, *camera, tuple(batch["images"].shape[-2:]), losses["matches"]
        )
        total = losses["total"] + masks["total"]
        logged = {"train/loss": total, "train/loss_mask_dice": masks["dice"], "train/loss_mask_bce": masks["bce"]}
        logged.update({f"train/loss_{term}": losses[term] for term, w in self.criterion.weights.items() if w})
        self.log_dict(logged, batch_size=count)
        return total

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
        scored = self._scored(batch)
        predictions, ground_truth = self._predictions(outputs, batch), ground_truth_lanes(batch)
        if scored.any():
            self.metrics[stage].update(predictions[scored].metric_input(), ground_truth[scored].metric_input())
        if stage == "val" and batch_idx == 0 and self.num_pictures and not self.trainer.sanity_checking:
            self._log_pictures(batch, predictions, ground_truth, scored)

    def _log_metric(self, stage: str) -> None:
        """Log the metric of all ranks (the metric sums its states across ranks) and reset it."""
        metric = self.metrics[stage]
        self.log_dict({f"{stage}/{key}": value.float() for key, value in metric.compute().items()})
        metric.reset()

    def _log_pictures(
        self, batch: Mapping[str, Any], predictions: DenseLanes, ground_truth: DenseLanes, scored: Tensor
    ) -> None:
        if not self.trainer.is_global_zero:
            return
        head = self.net.head
        pictures = []
        for b in scored.nonzero()[:, 0][: self.num_pictures].tolist():
            lanes = predictions.lanes(b, visible_only=False), ground_truth.lanes(b, visible_only=True)
            camera = batch["images"][b, -1], batch["K"][b, -1], batch["T_lane_cam"][b, -1]
            pictures.append(prediction_picture(*camera, *lanes, head.x_range, (0.0, head.y_range[1])))
        log_pictures(self.trainer, "val/pictures", pictures)

    # --------------------------------------------------------------- prediction
    def predict_step(self, batch: Mapping[str, Any], batch_idx: int) -> PredictionBatch:
        """Dense lanes of the real frames of the batch (see :class:`PredictionBatch`)."""
        outputs = self(batch)
        real = ~batch["padding"]
        timestamps = batch["timestamp_ns"][:, -1].tolist()
        return PredictionBatch(
            file_paths=[frame_path(c, t) for c, t, r in zip(batch["clip_id"], timestamps, real.tolist()) if r],
            labeled=batch["labeled"][real, -1],
            K=batch["K"][real, -1],
            T_lane_cam=batch["T_lane_cam"][real, -1],
            predictions=self._predictions(outputs, batch)[real],
            ground_truth=ground_truth_lanes(batch)[real],
        )

    # ---------------------------------------------------------------- optimiser
    def configure_optimizers(self) -> dict[str, Any]:
        groups = parameter_groups(self.net, self.lr, self.lr_multipliers)
        optimizer = torch.optim.AdamW(groups, lr=self.lr, betas=self.betas, weight_decay=self.weight_decay)
        total_steps = int(self.trainer.estimated_stepping_batches)
        scheduler = warmup_cosine(optimizer, self.warmup_steps, total_steps, self.min_lr / self.lr)
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}
