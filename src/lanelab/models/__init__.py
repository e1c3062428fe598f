"""Models: plain nn.Modules, configured by constructor arguments (see conf/model); every detector
offers the contract of ``api`` (:class:`LaneDetector`, trained with a :class:`LaneCriterion`)."""

from lanelab.models.api import DetectionOutputs, LaneCriterion, LaneDetector
from lanelab.models.backbone import ResNet
from lanelab.models.bi2lane import Bi2Lane
from lanelab.models.categories import (
    BACKGROUND_INDEX,
    NUM_LANE_CATEGORIES,
    category_to_index,
    index_to_category,
)
from lanelab.models.decoder import DecoderLayer, LaneDecoder
from lanelab.models.deformable_attention import DeformableCrossAttention
from lanelab.models.fpn import FPN
from lanelab.models.heads import LaneHead
from lanelab.models.losses import SparseLaneSTPLoss
from lanelab.models.matcher import HungarianMatcher
from lanelab.models.memory_queue import MemoryQueue, MemoryState
from lanelab.models.positional_encoding import PointPositionalEncoding
from lanelab.models.query_init import LaneQueryGenerator
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.models.spatio_temporal_attention import SpatioTemporalAttention

__all__ = [
    "BACKGROUND_INDEX",
    "Bi2Lane",
    "FPN",
    "NUM_LANE_CATEGORIES",
    "DecoderLayer",
    "DeformableCrossAttention",
    "DetectionOutputs",
    "HungarianMatcher",
    "LaneCriterion",
    "LaneDecoder",
    "LaneDetector",
    "LaneHead",
    "LaneQueryGenerator",
    "MemoryQueue",
    "MemoryState",
    "PointPositionalEncoding",
    "ResNet",
    "SparseLaneSTP",
    "SparseLaneSTPLoss",
    "SpatioTemporalAttention",
    "category_to_index",
    "index_to_category",
]
