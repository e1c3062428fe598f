"""Losses. SparseLaneSTP's: detection (eq. 22-24), priors (LaneCPP spatial, eq. 12-13 temporal), their
sum over the decoder layers (``criterion``), the query generator's auxiliary instance-mask loss,
the lateral-offset map's dense loss (``lateral_offset``),
and the criterion the Lightning module calls with the model's outputs (``sparselanestp``).
Bi²Lane's: its criterion (``bi2lane``, eq. 12-14) and the auxiliary BEV segmentation
(``bev_segmentation``); it reuses the detection losses."""

from lanelab.models.losses.bev_segmentation import bev_lane_mask, bev_segmentation_loss
from lanelab.models.losses.bi2lane import Bi2LaneCriterion
from lanelab.models.losses.criterion import TERMS, SparseLaneSTPLoss
from lanelab.models.losses.detection import focal_loss, regression_loss, visibility_loss
from lanelab.models.losses.instance_mask import InstanceMaskLoss, lane_masks
from lanelab.models.losses.lateral_offset import LateralOffsetLoss, lateral_offset_targets
from lanelab.models.losses.priors import (
    curvature_excess,
    orthogonal_correspondence,
    parallelism_and_surface,
    temporal_consistency,
)
from lanelab.models.losses.sparselanestp import SparseLaneSTPCriterion, detection_inputs

__all__ = [
    "TERMS",
    "Bi2LaneCriterion",
    "InstanceMaskLoss",
    "LateralOffsetLoss",
    "SparseLaneSTPCriterion",
    "SparseLaneSTPLoss",
    "bev_lane_mask",
    "bev_segmentation_loss",
    "curvature_excess",
    "detection_inputs",
    "focal_loss",
    "lane_masks",
    "lateral_offset_targets",
    "orthogonal_correspondence",
    "parallelism_and_surface",
    "regression_loss",
    "temporal_consistency",
    "visibility_loss",
]
