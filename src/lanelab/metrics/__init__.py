"""Lane-detection metrics.

- ``openlane``: the official OpenLane 3D-lane metric, reproduced, with SparseLaneSTP's
  long-range and Vis-IoU extensions; ``openlane_metric``: the same as a torchmetrics Metric.
- ``scenarios``: per-scenario tables; ``temporal_consistency``: frame-to-frame jitter.
- ``once``: the ONCE-3DLanes metric.
"""

from lanelab.json_files import LaneFileError
from lanelab.metrics.openlane import (
    FrameResult,
    OpenLaneConfig,
    evaluate,
    evaluate_frame,
    evaluate_frames,
    summarize,
)
from lanelab.openlane.read import OpenLaneFormatError

__all__ = [
    "FrameResult",
    "LaneFileError",
    "OpenLaneConfig",
    "OpenLaneFormatError",
    "evaluate",
    "evaluate_frame",
    "evaluate_frames",
    "summarize",
]
