"""The parts both detectors share: the image backbone (``backbone``) and its feature pyramid
(``fpn``), the prediction heads and lane representation (``heads``, SparseLaneSTP eq. 5-7; Bi²Lane's
refinement uses its MLPs and normalisers), the Hungarian matcher (``matcher``), the detection
losses (``detection_losses``, SparseLaneSTP eq. 22-24, Bi²Lane's classification of eq. 12) and the
lane NMS that prediction applies to either (``lane_nms``)."""

from lanelab.models.parts.backbone import ResNet
from lanelab.models.parts.detection_losses import focal_loss, regression_loss, visibility_loss
from lanelab.models.parts.fpn import FPN
from lanelab.models.parts.heads import LaneHead
from lanelab.models.parts.lane_nms import suppress_duplicates
from lanelab.models.parts.matcher import HungarianMatcher

__all__ = [
    "FPN",
    "HungarianMatcher",
    "LaneHead",
    "ResNet",
    "focal_loss",
    "regression_loss",
    "suppress_duplicates",
    "visibility_loss",
]
