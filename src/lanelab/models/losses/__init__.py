"""SparseLaneSTP losses: detection (eq. 22-24), priors (LaneCPP spatial, eq. 12-13 temporal), criterion;
the query generator's auxiliary instance-mask loss."""

from lanelab.models.losses.criterion import TERMS, SparseLaneSTPLoss
from lanelab.models.losses.detection import focal_loss, regression_loss, visibility_loss
from lanelab.models.losses.instance_mask import InstanceMaskLoss, lane_masks
from lanelab.models.losses.priors import (
    curvature_excess,
    orthogonal_correspondence,
    parallelism_and_surface,
    temporal_consistency,
)

__all__ = [
    "TERMS",
    "InstanceMaskLoss",
    "SparseLaneSTPLoss",
    "curvature_excess",
    "focal_loss",
    "lane_masks",
    "orthogonal_correspondence",
    "parallelism_and_surface",
    "regression_loss",
    "temporal_consistency",
    "visibility_loss",
]
