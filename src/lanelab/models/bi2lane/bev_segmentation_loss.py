"""The auxiliary BEV lane segmentation loss of Bi²Lane (eq. 14's L_seg), after PersFormer: the
ground-truth lanes drawn into the BEV grid as a binary mask, against the predicted mask's logits
with a binary cross-entropy (positive cells weighted up: lanes cover a few percent of the ground).

A cell is a lane cell when a real lane is visible at the cell's y and passes within half_width
of its centre (at least half a cell, so that thin lanes mark a cell in every row they cross).
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
import torch.nn.functional as F
from torch import Tensor

from lanelab.geometry import interpolate_in_y


def bev_lane_mask(targets: Mapping[str, Tensor], x: Tensor, y: Tensor, half_width: float) -> Tensor:
    """Lane masks (B, rows, columns) in {0, 1} of the ground truth (gt_y (B, S), gt_x / gt_vis
    (B, G, S), gt_mask (B, G)) on the grid of cell centres x (columns,), y (rows,), metres."""
    gt_x = targets["gt_x"]
    B, G, _ = gt_x.shape
    grid = targets["gt_y"].to(gt_x)[:, None].expand(B, G, -1)
    rows = y.to(gt_x)[None, None].expand(B, G, -1)
    lane_x, inside = interpolate_in_y(rows, grid, gt_x)  # (B, G, rows)
    lane_vis, _ = interpolate_in_y(rows, grid, targets["gt_vis"].to(gt_x))
    present = inside & (lane_vis > 0.5) & targets["gt_mask"][..., None]
    cell = float((x[1] - x[0]).abs()) if len(x) > 1 else 0.0
    near = (lane_x[..., None] - x.to(gt_x)).abs() <= max(half_width, cell / 2)  # (B, G, rows, columns)
    return (near & present[..., None]).any(1).to(gt_x.dtype)


def bev_segmentation_loss(
    logits: Tensor, targets: Mapping[str, Tensor], x: Tensor, y: Tensor, half_width: float, pos_weight: float
) -> Tensor:
    """Mean binary cross-entropy of lane-mask logits (B, rows, columns) against
    :func:`bev_lane_mask`, lane cells weighted by pos_weight. In float32 outside autocast."""
    mask = bev_lane_mask(targets, x, y, half_width)
    with torch.autocast(logits.device.type, enabled=False):
        weight = torch.tensor(pos_weight, dtype=torch.float32, device=logits.device)
        return F.binary_cross_entropy_with_logits(logits.float(), mask.float(), pos_weight=weight)
