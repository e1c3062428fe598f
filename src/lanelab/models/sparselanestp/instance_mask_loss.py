"""Auxiliary lane instance-segmentation loss of the query generator (SparseLaneSTP §3.2, §5.2:
"trained on the auxiliary task of lane instance segmentation similar to [33]", i.e. LATR).

It is what makes the N line embeddings lane-aware: without it the instance branch has no
signal of its own and the N proposals start out as near-copies of one another. As in LATR's
SparseInst branch, each ground-truth lane is drawn as a mask at the resolution of the predicted
instance masks, predictions and lanes are paired by Hungarian matching on the dice cost, and
the matched pairs pay a dice loss and a per-pixel binary cross-entropy (unmatched masks pay
nothing). LATR weighs them 2 (dice) and 5 (BCE). Given the detection loss's pairs, the masks use
those instead: a line whose mask follows one lane while its control points are trained on
another learns a fixed template rather than to find its lane in the image.

Ground-truth masks: the lane's visible samples (the ``gt_*`` grid) projected into the image,
joined by straight segments, each mask cell a segment passes marked 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
import torch.nn.functional as F
from scipy.optimize import linear_sum_assignment
from torch import Tensor, nn

from lanelab.geometry import project_lane_points

# Points per segment between neighbouring ground-truth samples when drawing: enough for 1 m
# samples 3 m ahead of a 720 x 960 camera, whose segments there span ~16 cells of stride 8.
_POINTS_PER_SEGMENT = 16


def lane_masks(
    points: Tensor, visible: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int],
    mask_size: tuple[int, int],
) -> Tensor:  # fmt: skip
    """Masks (B, G, h, w) in {0, 1} of lanes points (B, G, S, 3) (lane frame, y ascending) whose
    samples visible (B, G, S) bool are drawn, seen by cameras K (B, 3, 3) (pixels of images of
    image_size (H, W)) and T_lane_cam (B, 4, 4), at mask_size (h, w) covering the image."""
    B, G = points.shape[:2]
    (H, W), (h, w) = image_size, mask_size
    t = torch.linspace(0, 1, _POINTS_PER_SEGMENT, dtype=points.dtype, device=points.device)[:, None]
    start, end = points[:, :, :-1, None], points[:, :, 1:, None]
    dense = (start + t * (end - start)).flatten(2, 3)  # (B, G, (S - 1) * P, 3)
    drawn = (visible[..., :-1] & visible[..., 1:])[..., None].expand(-1, -1, -1, _POINTS_PER_SEGMENT).flatten(2)
    uv, _, in_front = project_lane_points(dense, K[:, None].to(points), T_lane_cam[:, None].to(points))
    column = torch.floor(uv[..., 0] * (w / W)).nan_to_num(-1).long()
    row = torch.floor(uv[..., 1] * (h / H)).nan_to_num(-1).long()
    drawn = drawn & in_front & (column >= 0) & (column < w) & (row >= 0) & (row < h)
    cell = torch.where(drawn, row * w + column, 0)
    masks = points.new_zeros(B, G, h * w).scatter_reduce(-1, cell, drawn.to(points.dtype), reduce="amax")
    return masks.view(B, G, h, w)


def dice_cost(probability: Tensor, target: Tensor) -> Tensor:
    """1 - dice coefficient 2 Σ p t / (Σ p² + Σ t²) (SparseInst) of every pair: probability
    (B, N, P), target (B, G, P) -> (B, N, G)."""
    overlap = probability @ target.transpose(1, 2)
    norms = probability.square().sum(-1)[:, :, None] + target.square().sum(-1)[:, None, :]
    return 1 - 2 * overlap / norms.clamp_min(1e-6)


class InstanceMaskLoss(nn.Module):
    """dice_weight, bce_weight: weights of the two terms (LATR: 2, 5)."""

    def __init__(self, dice_weight: float, bce_weight: float) -> None:
        super().__init__()
        self.dice_weight, self.bce_weight = dice_weight, bce_weight

    def forward(
        self, mask_logits: Tensor, targets: Mapping[str, Tensor], K: Tensor, T_lane_cam: Tensor,
        image_size: tuple[int, int], matches: Sequence[tuple[Tensor, Tensor]] | None = None,
    ) -> dict[str, Tensor]:  # fmt: skip
        """mask_logits (B, N, h, w); targets: gt_y (B, S), gt_x / gt_z / gt_vis (B, G, S),
        gt_mask (B, G); K (B, 3, 3), T_lane_cam (B, 4, 4) of the current frame, whose images
        have image_size (H, W); matches: per image (line index, lane index) pairs to use, e.g.
        the detection loss's, or None: pair by the dice cost. Returns "dice", "bce" (means over
        the matched pairs) and "total", their weighted sum."""
        x = targets["gt_x"]
        points = torch.stack([x, targets["gt_y"][:, None].expand_as(x), targets["gt_z"]], dim=-1)
        masks = lane_masks(points, targets["gt_vis"] > 0.5, K, T_lane_cam, image_size, tuple(mask_logits.shape[-2:]))
        logits, masks = mask_logits.flatten(2).float(), masks.flatten(2)
        cost = dice_cost(logits.sigmoid(), masks)  # (B, N, G)
        dice, bce = [], []
        for b, real in enumerate(targets["gt_mask"]):  # the solver is per image
            if matches is not None:
                pred, gt = (index.to(cost.device) for index in matches[b])
            else:
                lanes = real.nonzero()[:, 0]
                rows, columns = linear_sum_assignment(cost[b][:, lanes].detach().cpu().numpy())
                pred, gt = torch.as_tensor(rows, device=cost.device), lanes[torch.as_tensor(columns, device=cost.device)]
            dice.append(cost[b, pred, gt])
            bce.append(F.binary_cross_entropy_with_logits(logits[b, pred], masks[b, gt], reduction="none").mean(-1))
        dice, bce = torch.cat(dice), torch.cat(bce)
        if dice.numel() == 0:  # no lane in the batch: nothing to segment
            dice = bce = mask_logits.sum()[None] * 0.0
        dice, bce = dice.mean(), bce.mean()
        return {"dice": dice, "bce": bce, "total": self.dice_weight * dice + self.bce_weight * bce}
