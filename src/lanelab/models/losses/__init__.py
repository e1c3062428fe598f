"""SparseLaneSTP losses: detection (eq. 22-24), priors (LaneCPP spatial, eq. 12-13 temporal), criterion."""

from lanelab.models.losses.criterion import TERMS, SparseLaneSTPLoss
from lanelab.models.losses.detection import focal_loss, regression_loss, visibility_loss
from lanelab.models.losses.priors import (
    curvature_excess,
    orthogonal_correspondence,
    parallelism_and_surface,
    temporal_consistency,
)

__all__ = [
    "TERMS",
    "SparseLaneSTPLoss",
    "curvature_excess",
    "focal_loss",
    "orthogonal_correspondence",
    "parallelism_and_surface",
    "regression_loss",
    "temporal_consistency",
    "visibility_loss",
]
