"""Lane-detection metrics. ``openlane``: the official OpenLane 3D-lane metric, reproduced."""

from lanelab.metrics.openlane import (
    FrameResult,
    OpenLaneConfig,
    evaluate,
    evaluate_frame,
    summarize,
)
from lanelab.metrics.openlane_io import OpenLaneFormatError

__all__ = [
    "FrameResult",
    "OpenLaneConfig",
    "OpenLaneFormatError",
    "evaluate",
    "evaluate_frame",
    "summarize",
]
