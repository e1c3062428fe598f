"""Models: plain nn.Modules, configured by constructor arguments (see conf/model).

The detector contract is here: ``api`` (:class:`LaneDetector`, trained with a
:class:`LaneCriterion`) and ``categories`` (the class indices of the OpenLane categories). Below it,
one package per detector with its model, its own parts and its loss (``sparselanestp``,
``bi2lane``), and the parts both share (``parts``); models/README.md maps the papers' equations
to the files that hold them. Running a model (CUDA graphs, the operator log, the recorded top-k
picks) is :mod:`lanelab.runtime`'s, exporting it :mod:`lanelab.deploy`'s.
"""

from lanelab.models.api import DetectionOutputs, LaneCriterion, LaneDetector
from lanelab.models.categories import (
    BACKGROUND_INDEX,
    NUM_LANE_CATEGORIES,
    category_to_index,
    index_to_category,
)

__all__ = [
    "BACKGROUND_INDEX",
    "NUM_LANE_CATEGORIES",
    "DetectionOutputs",
    "LaneCriterion",
    "LaneDetector",
    "category_to_index",
    "index_to_category",
]
