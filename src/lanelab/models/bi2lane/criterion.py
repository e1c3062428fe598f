"""Bi²Lane's criterion (§III-D, eq. 12-14), as the Lightning module calls it with the model's outputs
(``Bi2Lane.forward`` / ``step``) and the batch (:class:`~lanelab.models.api.LaneCriterion`).

On the frames that count (:func:`~lanelab.models.api.scored_frames`):
- assignment: proposals are paired with ground-truth lanes by their anchors (Anchor3DLane's
  positive assignment on anchors: :class:`~lanelab.models.parts.HungarianMatcher` with
  ``match_on="anchors"``, the anchors' (x, z) against each lane, one-to-many with
  ``positive_distance``); unpaired proposals are background;
- "cls" (eq. 12): focal loss over the K categories + background of every proposal (the shared
  ``focal_loss``; eq. 12's α is one weight for all classes, as in Anchor3DLane, so λ_cls holds it),
  summed over the proposals and divided by the number of positives, as Anchor3DLane (and
  RetinaNet) normalise it: with thousands of anchors a mean over proposals would drown the few
  that hold a lane;
- "reg" (eq. 13, first two sums): visibility-weighted L1 of x and z of the paired proposals at
  the ground truth's samples (the shared ``regression_loss``);
- "vis" (eq. 13, last sum): L1 between predicted and true visibility (``visibility="l1"``, as
  printed) or the shared binary cross-entropy (``"bce"``);
- "seg" (eq. 14): the auxiliary BEV lane segmentation (:mod:`.bev_segmentation_loss`);
- "refine": the lanes each BDTR step detected in the history frames (outputs "detections", moved
  into the current frame), visibility-weighted L1 of x and z against the paired lane. The paper
  is silent on how the refinement offsets (eq. 2) learn; as Anchor3DLane supervises every stage
  of its iterative regression, every step is supervised here, with the pairs of the final
  proposals (lanes are static in the world, so the current frame's lanes are the history
  frames' too). Weight 0 leaves the offsets to learn only through the features they sample.
Every term is a per-sample mean; "total" is eq. 14 with the weights (λ) of ``weights``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import interpolate_in_y
from lanelab.geometry.curves import LaneCurves
from lanelab.models.api import TARGET_KEYS, scored_frames
from lanelab.models.bi2lane.bev_segmentation_loss import bev_segmentation_loss
from lanelab.models.categories import category_to_index
from lanelab.models.parts.detection_losses import focal_loss, regression_loss, visibility_loss
from lanelab.models.parts.matcher import HungarianMatcher

TERMS = ("cls", "reg", "vis", "refine", "seg")
VISIBILITY_LOSSES = ("l1", "bce")


class Bi2LaneCriterion(nn.Module):
    """matcher: pairs proposals with lanes; weights: {term: weight} over TERMS (missing: 0);
    y_range, num_points M: the proposals' fixed y (the net's); gamma: focal parameter;
    visibility: "l1" (eq. 13) or "bce"; seg_half_width (metres) and seg_pos_weight: the BEV
    lane mask's half width and the weight of its lane cells."""

    def __init__(
        self,
        matcher: HungarianMatcher,
        weights: Mapping[str, float],
        *,
        y_range: Sequence[float],
        num_points: int,
        gamma: float,
        visibility: str,
        seg_half_width: float,
        seg_pos_weight: float,
    ) -> None:
        super().__init__()
        unknown = set(weights) - set(TERMS)
        if unknown:
            raise ValueError(f"unknown loss terms {sorted(unknown)}; known: {TERMS}")
        if visibility not in VISIBILITY_LOSSES:
            raise ValueError(f"visibility must be one of {VISIBILITY_LOSSES}, got {visibility!r}")
        self.matcher = matcher
        self.weights = {term: float(weights.get(term, 0.0)) for term in TERMS}
        self.curves = LaneCurves("discrete", num_points, tuple(y_range))
        self.gamma, self.visibility = gamma, visibility
        self.seg_half_width, self.seg_pos_weight = seg_half_width, seg_pos_weight

    def forward(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> dict[str, Tensor]:
        """outputs: Bi2Lane's (points (1, B, A, M, 4), logits (1, B, A, K + 1), anchors (A, M, 3),
        detections (B, S, A, M, 3), detection_valid (B, S), and with a BEV branch bev_logits,
        bev_x, bev_y); batch: the collated batch (lanelab.models.api). Returns "total" and every
        term of non-zero weight; only "total" where no frame counts."""
        if self.weights["seg"] and "bev_logits" not in outputs:
            raise ValueError("criterion.weights.seg > 0 needs the model's BEV branch (model.net.bev) in training mode")
        scored = scored_frames(batch)
        if not bool(scored.any()):
            # Nothing to learn from; a zero that reaches every output keeps DDP ranks in step.
            tensors = [value for value in outputs.values() if isinstance(value, Tensor) and value.is_floating_point()]
            return {"total": sum((value.sum() * 0.0 for value in tensors), outputs["points"].new_zeros(()))}
        targets = {key: batch[key][scored] for key in TARGET_KEYS}
        points, logits = outputs["points"][-1, scored], outputs["logits"][-1, scored]  # (B', A, M, 4), (B', A, K + 1)
        y = targets["gt_y"].to(points)
        curves = self.curves.sample(points, y)  # (B', A, S, 4)
        anchors = outputs["anchors"].to(points)
        anchors = torch.cat([anchors, torch.ones_like(anchors[..., :1])], -1).expand(points.shape[0], -1, -1, -1)
        anchor_xz = self.curves.sample(anchors, y)[..., [0, 2]]  # (B', A, S, 2)
        matches = self.matcher(logits, curves, targets, anchor_xz)
        image = torch.cat([torch.full_like(pred, b) for b, (pred, _) in enumerate(matches)])
        pred = torch.cat([pred for pred, _ in matches])
        gt = torch.cat([gt for _, gt in matches])

        target = torch.full(logits.shape[:2], logits.shape[-1] - 1, dtype=torch.long, device=logits.device)
        target[image, pred] = category_to_index(targets["gt_category"][image, gt])
        matched = curves[image, pred]  # (P, S, 4)
        gt_x, gt_z, gt_vis = (targets[key][image, gt].to(curves) for key in ("gt_x", "gt_z", "gt_vis"))
        losses = {
            "cls": focal_loss(logits.float(), target, self.gamma) * target.numel() / max(len(pred), 1),
            "reg": regression_loss(matched, gt_x, gt_z, gt_vis, gt_vis.sum().clamp(min=1)),
            "vis": self._visibility(matched, gt_vis),
        }
        if self.weights["refine"]:
            detections = outputs["detections"][scored][image, :, pred]  # (P, R, M, 3)
            valid = outputs["detection_valid"][scored][image]  # (P, R)
            losses["refine"] = self._refinement(detections, valid, y[image], gt_x, gt_z, gt_vis)
        if self.weights["seg"]:
            losses["seg"] = bev_segmentation_loss(
                outputs["bev_logits"][scored], targets, outputs["bev_x"], outputs["bev_y"], self.seg_half_width,
                self.seg_pos_weight,
            )  # fmt: skip
        terms = {term: value for term, value in losses.items() if self.weights[term]}
        return {"total": sum(self.weights[term] * value for term, value in terms.items()), **terms}

    def _visibility(self, matched: Tensor, gt_vis: Tensor) -> Tensor:
        """Eq. 13's last sum, per sample: L1 or the binary cross-entropy."""
        if self.visibility == "bce":
            return visibility_loss(matched, gt_vis, max(gt_vis.numel(), 1))
        return F.l1_loss(matched[..., 3].float(), gt_vis.float(), reduction="sum") / max(gt_vis.numel(), 1)

    @staticmethod
    def _refinement(
        detections: Tensor, valid: Tensor, grid_y: Tensor, gt_x: Tensor, gt_z: Tensor, gt_vis: Tensor
    ) -> Tensor:
        """Visibility-weighted L1 of x and z of the paired lines' BDTR detections (P, R, M, 3) in
        the current frame, of real frames valid (P, R), against their lanes given at grid_y
        (P, S): the lane interpolated at each detected point's y, no weight outside its samples."""
        P, R, M, _ = detections.shape
        if P == 0 or R == 0:
            return detections.sum() * 0.0
        points = detections.reshape(P, R * M, 3).float()
        lane_x, inside = interpolate_in_y(points[..., 1], grid_y.float(), gt_x.float())
        lane_z, _ = interpolate_in_y(points[..., 1], grid_y.float(), gt_z.float())
        lane_vis, _ = interpolate_in_y(points[..., 1], grid_y.float(), gt_vis.float())
        weight = lane_vis * inside * valid[:, :, None].expand(P, R, M).reshape(P, R * M)
        return regression_loss(points, lane_x, lane_z, weight, weight.sum().clamp(min=1))
