"""SparseLaneSTP (Pittner et al.): the detector (``model``, Fig. 1) and its own parts, the lane
query generator (``query_init``, §3.2), the decoder layer (``decoder``, eq. 3-4) with its
spatio-temporal attention (``spatio_temporal_attention`` and its neighbourhoods ``sta_masks``,
§3.3) and deformable cross-attention (``deformable_attention``, eq. 4), the memory queue
(``memory_queue``, eq. 8-10), the positional encodings (``positional_encoding``, eq. 11;
``ground_encoding``, LATR's), the repository's lateral search and lateral-offset map
(``lateral_search``, ``lateral_offset``); and its loss: the criterion the Lightning module calls
(``criterion``), the detection losses of every decoder layer with the priors
(``deep_supervision``, eq. 21-24; ``priors``, LaneCPP's and eq. 12-13), the query generator's
instance masks (``instance_mask_loss``) and the lateral-offset map's loss
(``lateral_offset_loss``). The LATR-like baseline is a configuration of this detector
(conf/model/latr_baseline.yaml). The parts it shares with Bi²Lane: :mod:`lanelab.models.parts`."""

from lanelab.models.sparselanestp.criterion import SparseLaneSTPCriterion
from lanelab.models.sparselanestp.decoder import DecoderLayer, LaneDecoder
from lanelab.models.sparselanestp.deep_supervision import TERMS, SparseLaneSTPLoss
from lanelab.models.sparselanestp.deformable_attention import DeformableCrossAttention
from lanelab.models.sparselanestp.instance_mask_loss import InstanceMaskLoss
from lanelab.models.sparselanestp.lateral_offset_loss import LateralOffsetLoss
from lanelab.models.sparselanestp.memory_queue import MemoryQueue, MemoryState, QueueState
from lanelab.models.sparselanestp.model import SparseLaneSTP
from lanelab.models.sparselanestp.positional_encoding import PointPositionalEncoding
from lanelab.models.sparselanestp.query_init import LaneQueryGenerator
from lanelab.models.sparselanestp.spatio_temporal_attention import SpatioTemporalAttention

__all__ = [
    "TERMS",
    "DecoderLayer",
    "DeformableCrossAttention",
    "InstanceMaskLoss",
    "LaneDecoder",
    "LaneQueryGenerator",
    "LateralOffsetLoss",
    "MemoryQueue",
    "MemoryState",
    "PointPositionalEncoding",
    "QueueState",
    "SparseLaneSTP",
    "SparseLaneSTPCriterion",
    "SparseLaneSTPLoss",
    "SpatioTemporalAttention",
]
