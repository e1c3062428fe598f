"""Bi²Lane (Li et al.): anchors (``anchors``, eq. 1, 3), bi-directional temporal refinement
(``refinement``, eq. 2-6), bi-level feature aggregation (``aggregation``, eq. 7-11; its point
level's attention: ``single_query_attention``), the auxiliary BEV branch (``bev``), the streaming
cache (``frame_cache``) and the detector (``model``); its criterion (``criterion``, eq. 12-14)
with the auxiliary BEV segmentation loss (``bev_segmentation_loss``). Bi²Lane's baseline is a
configuration of this detector (conf/model/bi2lane_baseline.yaml). The parts it shares with
SparseLaneSTP: :mod:`lanelab.models.parts`."""

from lanelab.models.bi2lane.aggregation import BiLevelAggregation
from lanelab.models.bi2lane.anchors import anchor_families, ego_motion, move_points, sample_features, sampling_grid
from lanelab.models.bi2lane.bev import BEVSegmentation
from lanelab.models.bi2lane.bev_segmentation_loss import bev_lane_mask, bev_segmentation_loss
from lanelab.models.bi2lane.criterion import Bi2LaneCriterion
from lanelab.models.bi2lane.frame_cache import FrameCache
from lanelab.models.bi2lane.model import Bi2Lane
from lanelab.models.bi2lane.refinement import TemporalRefinement, refine

__all__ = [
    "BEVSegmentation",
    "BiLevelAggregation",
    "Bi2Lane",
    "Bi2LaneCriterion",
    "FrameCache",
    "TemporalRefinement",
    "anchor_families",
    "bev_lane_mask",
    "bev_segmentation_loss",
    "ego_motion",
    "move_points",
    "refine",
    "sample_features",
    "sampling_grid",
]
