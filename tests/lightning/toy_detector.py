"""A second detector in a few lines, to show that a model is its detector, its loss and one config:
a small CNN pools the current image into one feature vector, from which linear layers predict N
lines of M points at fixed y (LATR's discrete points, one stage) and their classes.

It implements lanelab.models.api.LaneDetector; ToyLoss is its LaneCriterion.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import control_point_y
from lanelab.geometry.curves import LaneCurves
from lanelab.models.api import FRAME_KEYS, DetectionOutputs, scored_frames
from lanelab.models.categories import NUM_LANE_CATEGORIES, category_to_index


class ToyDetector(nn.Module):
    """num_lines N, num_points M over y_range (metres); x of the points in metres, unbounded."""

    def __init__(self, num_lines: int, num_points: int, y_range: tuple[float, float]) -> None:
        super().__init__()
        self.num_lines, self.num_points = num_lines, num_points
        self.features = nn.Sequential(
            nn.Conv2d(3, 8, 3, stride=2, padding=1), nn.ReLU(), nn.Conv2d(8, 16, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(1), nn.Flatten(),
        )  # fmt: skip
        self.points = nn.Linear(16, num_lines * num_points * 2)  # x and visibility logit per point
        self.classes = nn.Linear(16, num_lines * (NUM_LANE_CATEGORIES + 1))
        self.curves = LaneCurves("discrete", num_points, tuple(y_range))
        self.register_buffer("y", control_point_y(num_points, *y_range), persistent=False)

    def forward(self, batch: Mapping[str, Any]) -> DetectionOutputs:
        """The current frame alone: no memory."""
        return self.step({key: batch[key][:, -1] for key in FRAME_KEYS})

    def step(self, frame: Mapping[str, Tensor]) -> DetectionOutputs:
        features = self.features(frame["images"])  # (B, 16)
        B, N, M = features.shape[0], self.num_lines, self.num_points
        x, v = self.points(features).view(B, N, M, 2).unbind(-1)
        points = torch.stack([x, self.y.expand_as(x), torch.zeros_like(x), v.sigmoid()], dim=-1)
        return {"points": points[None], "logits": self.classes(features).view(1, B, N, -1)}

    def reset(self, mask: Tensor) -> None:
        """No streaming state to empty."""

    def decode(self, outputs: Mapping[str, Any], y: Tensor) -> Tensor:
        dense = self.curves.sample(outputs["points"][-1], y.to(outputs["points"]))
        x, _, z, v = dense.unbind(-1)
        return torch.stack([x, y.to(x).expand_as(x), z, v], dim=-1)


class ToyLoss(nn.Module):
    """Line i learns ground-truth lane i (no matching): L1 of x over the lane's visible samples,
    visibility BCE, and cross-entropy of the classes (background for lines without a lane).
    y_range: the detector's, where its points lie."""

    def __init__(self, y_range: tuple[float, float]) -> None:
        super().__init__()
        self.y_range = tuple(y_range)

    def forward(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> dict[str, Tensor]:
        scored = scored_frames(batch)
        points, logits = outputs["points"][-1, scored], outputs["logits"][-1, scored]  # (B', N, M, 4), (B', N, K + 1)
        if not bool(scored.any()):
            return {"total": points.sum() * 0.0 + logits.sum() * 0.0}
        N = points.shape[1]
        lanes = {key: batch[key][scored][:, :N] for key in ("gt_x", "gt_vis", "gt_category", "gt_mask")}
        curves = LaneCurves("discrete", points.shape[2], self.y_range)
        sampled = curves.sample(points, batch["gt_y"][scored])[:, : lanes["gt_x"].shape[1]]  # (B', G', S, 4)
        visible = lanes["gt_vis"] * lanes["gt_mask"][..., None]
        x = ((sampled[..., 0] - lanes["gt_x"]).abs() * visible).sum() / visible.sum().clamp_min(1)
        vis = F.binary_cross_entropy(sampled[..., 3].clamp(1e-4, 1 - 1e-4), lanes["gt_vis"], reduction="none")
        vis = (vis * lanes["gt_mask"][..., None]).sum() / (lanes["gt_mask"].sum() * vis.shape[-1]).clamp_min(1)
        target = torch.full(logits.shape[:2], NUM_LANE_CATEGORIES, dtype=torch.long, device=logits.device)
        G = lanes["gt_mask"].shape[1]
        target[:, :G] = torch.where(lanes["gt_mask"], category_to_index(lanes["gt_category"]), NUM_LANE_CATEGORIES)
        cls = F.cross_entropy(logits.flatten(0, 1), target.flatten())
        return {"total": x + vis + cls, "x": x, "vis": vis, "cls": cls}
