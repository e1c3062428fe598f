"""Lightning wiring: the LightningModule of every lane detector, its predictions and their files.

- ``module``: :class:`LaneDetectionModule` (training, validation, prediction of any
  :class:`lanelab.models.api.LaneDetector`);
- ``predictions``: model outputs and ground truth as dense lanes;
- ``openlane_writer``: :class:`OpenLaneWriter`, prediction files in OpenLane's JSON format;
- ``pictures``: pictures of predictions for the logs; ``optim``: optimisers and lr schedules;
- ``console``: the progress bar, the model summary and Lightning's log lines on the console;
- ``lr_monitor``: the learning rate in the logs;
- ``legacy``: ``SparseLaneSTPModule``, which the run configs of older checkpoints name.
"""

from lanelab.lightning.legacy import SparseLaneSTPModule
from lanelab.lightning.module import LaneDetectionModule
from lanelab.lightning.openlane_writer import OpenLaneWriter
from lanelab.lightning.predictions import DenseLanes, PredictionBatch

__all__ = ["DenseLanes", "LaneDetectionModule", "OpenLaneWriter", "PredictionBatch", "SparseLaneSTPModule"]
