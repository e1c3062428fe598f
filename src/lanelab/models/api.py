"""The detector contract: what every lane detector offers, what its outputs hold and what its
criterion is called with (DESIGN.md, "Model contract").

:class:`lanelab.lightning.LaneDetectionModule` trains, validates and predicts any detector
through this contract alone, and :mod:`lanelab.lightning.predictions` turns its outputs into
lanes; a new model is a :class:`LaneDetector`, a :class:`LaneCriterion` and one config.

Batches are the collated samples of :mod:`lanelab.data.dataset`: F frames per sample, oldest
first, the current frame last, and the current frame's ground truth:

==================  =================  ===============================================
key                 shape              meaning
==================  =================  ===============================================
images              (B, F, 3, H, W)    normalised RGB
K                   (B, F, 3, 3)       intrinsics, in pixels of the images as given
T_lane_cam          (B, F, 4, 4)       camera extrinsic
T_world_lane        (B, F, 4, 4)       ego pose (float64)
valid               (B, F) bool        False for padding before a clip's start
labeled             (B, F) bool        the frame has lane labels
reset               (B,) bool          a stream starts a clip: empty the streaming state first
padding             (B,) bool          repeats another sample; counts nowhere
gt_y                (B, S)             the y grid (metres) of the ground truth
gt_x, gt_z, gt_vis  (B, G, S)          the current frame's lanes at gt_y
gt_category         (B, G)             OpenLane category ids
gt_mask             (B, G) bool        the real lanes (G is padded)
==================  =================  ===============================================

Outputs (:class:`DetectionOutputs`) are a dict with at least ``points`` and ``logits`` for the
current frame; a detector may add keys of its own (SparseLaneSTP: its initial points, instance
masks, line anchors, the memory it attended to), which only its criterion reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, TypedDict, runtime_checkable

from torch import Tensor

# What a streaming step receives of a frame (besides ``reset``), each without the frame axis.
FRAME_KEYS = ("images", "K", "T_lane_cam", "T_world_lane")
# The current frame's ground truth in a batch.
TARGET_KEYS = ("gt_y", "gt_x", "gt_z", "gt_vis", "gt_category", "gt_mask")


class DetectionOutputs(TypedDict):
    """What every detector returns for the current frame of B samples.

    points: (L, B, N, M, 4) N line proposals of M points (x, y, z, visibility), metres and
        [0, 1], for each of L stages (decoder layers; deep supervision); [-1] is the prediction.
        What the points are (curve control points, samples at fixed y) is the detector's:
        ``decode`` makes lanes of them.
    logits: (L, B, N, K + 1) class logits per stage: the K lane categories of
        :mod:`lanelab.models.categories`, then the background.
    """

    points: Tensor
    logits: Tensor


@runtime_checkable
class LaneDetector(Protocol):
    """A lane detector: a plain ``nn.Module`` that runs windowed (``forward``) or streaming
    (``reset`` / ``step``) and decodes its outputs into dense lanes."""

    def __call__(self, batch: Mapping[str, Any]) -> DetectionOutputs:
        """``forward``, as an ``nn.Module`` is called."""
        ...

    def forward(self, batch: Mapping[str, Any]) -> DetectionOutputs:
        """The current (last) frame's outputs for a batch of F-frame windows (keys as above;
        the ground truth is read only in training, by a detector that takes it as input there,
        as SparseLaneSTP's query denoising does). A detector without memory of earlier frames
        looks at the current frame alone."""
        ...

    def step(self, frame: Mapping[str, Tensor]) -> DetectionOutputs:
        """One streaming step: frame holds ``FRAME_KEYS`` without the frame axis (images
        (B, 3, H, W), ...) and ``reset`` (B,) bool, which calls ``reset`` first. The detector
        carries its streaming state (if any) from step to step."""
        ...

    def reset(self, mask: Tensor) -> None:
        """Empty the streaming state of the streams where mask (B,) bool is True. An all-True
        mask of any length empties every stream (what each evaluation run starts with)."""
        ...

    def decode(self, outputs: Mapping[str, Any], y: Tensor) -> Tensor:
        """Dense lanes (B, N, S, 4) = (x, y, z, visibility) of the last stage's points, at the
        longitudinal positions y (S,), metres."""
        ...


@runtime_checkable
class LaneCriterion(Protocol):
    """A detector's training loss, an ``nn.Module`` called with the outputs as the detector
    returned them and the whole batch."""

    def __call__(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> dict[str, Tensor]:
        """Scalar tensors: "total", the loss to minimise over the frames that count
        (:func:`scored_frames`), and any terms to log beside it. Where no frame counts, "total"
        is a zero that still depends on every output (so that every rank of a DDP run takes
        the same step)."""
        ...


def scored_frames(batch: Mapping[str, Any]) -> Tensor:
    """(B,) bool: the samples that count towards the loss and the metrics, those whose
    current frame is labeled and that are not padding."""
    return batch["labeled"][:, -1] & ~batch["padding"]
