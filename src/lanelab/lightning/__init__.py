"""Lightning wiring: the SparseLaneSTP LightningModule, its predictions and their files.

- ``sparselanestp_module``: :class:`SparseLaneSTPModule` (training, validation, prediction);
- ``predictions``: model outputs and ground truth as dense lanes;
- ``openlane_writer``: :class:`OpenLaneWriter`, prediction files in OpenLane's JSON format;
- ``pictures``: pictures of predictions for the logs; ``optim``: LATR's optimiser schedule.
"""

from lanelab.lightning.openlane_writer import OpenLaneWriter
from lanelab.lightning.predictions import DenseLanes, Lane, PredictionBatch
from lanelab.lightning.sparselanestp_module import SparseLaneSTPModule

__all__ = ["DenseLanes", "Lane", "OpenLaneWriter", "PredictionBatch", "SparseLaneSTPModule"]
