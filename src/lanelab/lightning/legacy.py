"""Checkpoints of the SparseLaneSTP-only LightningModule that LaneDetectionModule replaced.

Their run config (which ``lanelab-eval checkpoint=...`` rebuilds the model from) says
``_target_: lanelab.lightning.SparseLaneSTPModule`` with that module's keys; this function
builds the same model as a :class:`LaneDetectionModule` from them. The state dict is the same:
the detector's weights under ``net.``, nothing else.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

from lanelab.lightning.module import BackboneStart, LaneDetectionModule
from lanelab.lightning.optim import adamw, warmup_cosine
from lanelab.metrics.openlane import OpenLaneConfig
from lanelab.models.sparselanestp import InstanceMaskLoss, SparseLaneSTP, SparseLaneSTPCriterion, SparseLaneSTPLoss

PICTURE_HEIGHT = 360  # pixels: what that module drew its pictures at


def SparseLaneSTPModule(  # noqa: N802 (the class name the old run configs hold)
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
) -> LaneDetectionModule:
    """The LaneDetectionModule of an old run config's ``model`` node: the keys mean what they
    meant there (backbone and nms_distance were added later: checkpoints from before have
    neither, and had no NMS); the top views of the pictures cover the head's x range and y up
    to its end, as that module drew them."""
    head = net.head
    return LaneDetectionModule(
        net,
        SparseLaneSTPCriterion(criterion, mask_criterion),
        metric=OpenLaneConfig(**metric),
        optimizer=partial(adamw, lr=lr, weight_decay=weight_decay, betas=betas, lr_multipliers=lr_multipliers),
        scheduler=partial(warmup_cosine, warmup_steps=warmup_steps, min_lr=min_lr),
        pictures={
            "num_frames": num_pictures, "height": PICTURE_HEIGHT, "x_range": head.x_range,
            "y_range": (0.0, head.y_range[1]),
        },  # fmt: skip
        nms_distance=nms_distance,
        backbone=backbone or {"weights": None},
    )
