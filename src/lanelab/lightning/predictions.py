"""Dense lanes: what the model's outputs and the ground truth of a batch become for metrics,
prediction files and pictures.

Both are :class:`DenseLanes`, N lane slots of B frames sampled at the same S longitudinal
positions (the batch's ``gt_y`` grid, so that predictions and ground truth are compared at the
same places). A proposal is a lane where its most likely class is not background (LATR's rule);
its category is the most likely lane class and its score that class's probability.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import Tensor

from lanelab.lanes import Lane
from lanelab.metrics.openlane_metric import LaneBatch
from lanelab.models.api import LaneDetector
from lanelab.models.categories import BACKGROUND_INDEX, index_to_category
from lanelab.models.parts.lane_nms import suppress_duplicates


@dataclass
class DenseLanes:
    """Lanes of B frames, N slots each, sampled at S longitudinal positions.

    points (B, N, S, 3) lane frame, metres; visibility (B, N, S) in [0, 1]; category (B, N)
    OpenLane ids; score (B, N); valid (B, N) bool, the slots that hold a lane; threshold: points
    of visibility at or below it are not part of their lane (0 for ground truth, the metric's
    visibility_threshold for predictions).
    """

    points: Tensor
    visibility: Tensor
    category: Tensor
    score: Tensor
    valid: Tensor
    threshold: float

    def __getitem__(self, frames: Tensor | slice) -> DenseLanes:
        """The frames selected by a (B,) bool mask, indices or a slice."""
        return DenseLanes(
            self.points[frames], self.visibility[frames], self.category[frames], self.score[frames],
            self.valid[frames], self.threshold,
        )  # fmt: skip

    def __len__(self) -> int:
        return self.points.shape[0]

    def metric_input(self) -> LaneBatch:
        """The OpenLaneMetric's input; the metric drops the points at or below the threshold."""
        return LaneBatch(self.points, self.visibility, self.category, self.valid)

    def lanes(self, frame: int, visible_only: bool) -> list[Lane]:
        """The lanes of one frame, with every sample or only those above the threshold (as
        prediction files hold them); lanes left with fewer than two points are dropped."""
        lanes = []
        for i in self.valid[frame].nonzero()[:, 0].tolist():
            points = self.points[frame, i].detach().cpu().double().numpy()
            visibility = self.visibility[frame, i].detach().cpu().double().numpy()
            keep = visibility > self.threshold if visible_only else np.ones(len(points), bool)
            if keep.sum() >= 2:
                category, score = int(self.category[frame, i]), float(self.score[frame, i])
                lanes.append(Lane(points[keep], visibility[keep], category, score=score))
        return lanes


def predicted_lanes(
    net: LaneDetector, outputs: Mapping[str, Any], y: Tensor, threshold: float, nms: tuple[float, float] | None
) -> DenseLanes:
    """The last stage's lanes at longitudinal positions y (S,), from the outputs of the
    detector's ``forward`` / ``step`` (lanelab.models.api: points decoded by ``net.decode``,
    logits (L, B, N, K + 1)). A line is a lane where a category outscores the background;
    nms = (distance, near range), metres: lanes within that mean lateral distance of a more
    confident one over y <= near range are dropped (models.parts.lane_nms), None: none."""
    dense = net.decode(outputs, y)  # (B, N, S, 4)
    probability = outputs["logits"][-1].float().softmax(-1)
    score, index = probability[..., :BACKGROUND_INDEX].max(-1)
    valid = probability.argmax(-1) != BACKGROUND_INDEX
    if nms is not None:
        distance, near = nms
        valid = suppress_duplicates(dense[..., 0], score, valid, y <= near, distance)
    return DenseLanes(
        points=dense[..., :3],
        visibility=dense[..., 3],
        category=index_to_category(index),
        score=score,
        valid=valid,
        threshold=threshold,
    )


def ground_truth_lanes(batch: Mapping[str, Tensor]) -> DenseLanes:
    """The current frame's ground truth of a collated batch: gt_y (B, S), gt_x / gt_z / gt_vis
    (B, G, S), gt_category (B, G), gt_mask (B, G)."""
    x, z = batch["gt_x"], batch["gt_z"]
    y = batch["gt_y"][:, None, :].expand_as(x)
    return DenseLanes(
        points=torch.stack([x, y, z], dim=-1),
        visibility=batch["gt_vis"],
        category=batch["gt_category"],
        score=batch["gt_mask"].to(x.dtype),
        valid=batch["gt_mask"],
        threshold=0.0,
    )


@dataclass
class PredictionBatch:
    """What ``predict_step`` returns for the B' real (not padding) frames of a batch (Lightning
    moves it to the CPU to collect it).

    file_paths: OpenLane ``file_path`` of each frame (:func:`lanelab.openlane.file_paths.store_file_path`:
    an OpenLane store's own); clip_ids and frame_indices (B',): where each frame lies in its
    store, so that its ground truth can be read as stored; labeled (B',) bool; predictions: every
    lane slot, see :class:`DenseLanes`.
    """

    file_paths: list[str]
    clip_ids: list[str]
    frame_indices: Tensor
    labeled: Tensor
    predictions: DenseLanes
