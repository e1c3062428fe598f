"""Bi²Lane (Li et al.): anchors (``anchors``), bi-directional temporal refinement (``refinement``),
bi-level feature aggregation (``aggregation``), the auxiliary BEV branch (``bev``), the streaming
cache (``frame_cache``) and the detector (``model``). Its criterion: lanelab.models.losses.bi2lane."""

from lanelab.models.bi2lane.aggregation import BiLevelAggregation
from lanelab.models.bi2lane.anchors import anchor_families, ego_motion, move_points, sample_features, sampling_grid
from lanelab.models.bi2lane.bev import BEVSegmentation
from lanelab.models.bi2lane.frame_cache import FrameCache
from lanelab.models.bi2lane.model import Bi2Lane
from lanelab.models.bi2lane.refinement import TemporalRefinement, refine

__all__ = [
    "BEVSegmentation",
    "BiLevelAggregation",
    "Bi2Lane",
    "FrameCache",
    "TemporalRefinement",
    "anchor_families",
    "ego_motion",
    "move_points",
    "refine",
    "sample_features",
    "sampling_grid",
]
