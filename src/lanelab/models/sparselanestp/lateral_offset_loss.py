"""The lateral-offset map's loss (models.sparselanestp.lateral_offset): a dense target from the lane labels.

Target: every map cell whose pixel ray meets the ground (the plane z = 0 of the lane frame, as
the ground positional encoding assumes) at (X, Y) with Y inside ``max_distance`` looks for the
nearest lane g visible at Y (lanes are functions of y: their x on the ground-truth grid, linearly
interpolated); its target is where (x_g(Y), Y, 0) lies across the image from the cell, in image
widths (the map's unit, models.sparselanestp.lateral_offset). Cells with such a lane within ``max_offset``
metres are confident (BCE target 1) and pay a smooth-L1 on the offset, measured in metres (the
image's scale at the cell), so near and far rows count alike; the rest of the road (between lanes
further apart than 2 max_offset, beyond every lane) is unconfident (target 0) and pays nothing on
the offset. Above the horizon and beyond max_distance nothing is trained.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import cell_centres, intersect_ground, project_lane_points


def lateral_offset_targets(
    targets: Mapping[str, Tensor],
    K: Tensor,
    T_lane_cam: Tensor,
    image_size: tuple[int, int],
    map_size: tuple[int, int],
    max_offset: float,
    max_distance: float,
) -> tuple[Tensor, Tensor, Tensor]:
    """targets: gt_y (B, S) (uniform, ascending), gt_x, gt_vis (B, G, S), gt_mask (B, G); K (B, 3, 3)
    in pixels of images of image_size (H, W); T_lane_cam (B, 4, 4); map_size (h, w) of the map.
    Returns the offset (B, h, w) in image widths, the metres per image width at each cell (B, h, w),
    the confidence target (B, h, w) in {0, 1} and the cells trained (B, h, w) bool."""
    width, (h, w) = image_size[1], map_size
    gt_y, gt_x = targets["gt_y"].float(), targets["gt_x"].float()
    B, G, S = gt_x.shape
    uv = cell_centres((h, w), image_size, gt_x.dtype, gt_x.device).expand(B, -1, -1)
    K, T_lane_cam = K.float(), T_lane_cam.float()
    ground, on_ground = intersect_ground(uv, K, T_lane_cam)  # (B, P, 3)
    X, Y = ground[..., 0].nan_to_num(0.0), ground[..., 1].nan_to_num(-1.0)

    # Each lane's x and visibility at every cell's Y, by linear interpolation on the uniform grid.
    position = (Y - gt_y[:, :1]) / (gt_y[:, 1:2] - gt_y[:, :1])  # (B, P) in grid steps
    index = position.floor().clamp(0, S - 2).long()
    fraction = (position - index).clamp(0, 1)[:, None]
    below, above = index[:, None].expand(-1, G, -1), (index + 1)[:, None].expand(-1, G, -1)
    lane_x = gt_x.gather(-1, below) * (1 - fraction) + gt_x.gather(-1, above) * fraction  # (B, G, P)
    inside = (position >= 0) & (position <= S - 1)
    gt_vis = targets["gt_vis"]
    visible = (gt_vis.gather(-1, below) > 0.5) & (gt_vis.gather(-1, above) > 0.5)
    visible = visible & targets["gt_mask"][..., None] & inside[:, None]

    distance = torch.where(visible, lane_x - X[:, None], torch.full_like(lane_x, float("inf")))
    nearest = distance.abs().argmin(1, keepdim=True)
    metres = distance.gather(1, nearest)[:, 0]  # (B, P)
    trained = on_ground & (Y <= max_distance) & inside
    confident = trained & (metres.abs() <= max_offset)
    lane_point = torch.stack([X + torch.where(confident, metres, torch.zeros_like(metres)), Y, torch.zeros_like(Y)], -1)
    lane_uv, _, _ = project_lane_points(lane_point, K, T_lane_cam)
    sideways, _, _ = project_lane_points(lane_point + lane_point.new_tensor([1.0, 0.0, 0.0]), K, T_lane_cam)
    widths = ((lane_uv[..., 0] - uv[..., 0]) / width).nan_to_num(0.0)
    metres_per_width = (width / (sideways[..., 0] - lane_uv[..., 0])).nan_to_num(0.0)
    confident = confident & (metres_per_width > 0)
    widths = torch.where(confident, widths, torch.zeros_like(widths))
    shape = (B, h, w)
    return widths.view(shape), metres_per_width.view(shape), confident.to(widths.dtype).view(shape), trained.view(shape)


class LateralOffsetLoss(nn.Module):
    """offset_weight: of the smooth-L1 (metres) on confident cells; confidence_weight: of the BCE
    on every trained cell; max_offset, max_distance: metres (see the module doc)."""

    def __init__(self, offset_weight: float, confidence_weight: float, max_offset: float, max_distance: float) -> None:
        super().__init__()
        self.offset_weight, self.confidence_weight = offset_weight, confidence_weight
        self.max_offset, self.max_distance = max_offset, max_distance

    def forward(
        self, offsets: Tensor, targets: Mapping[str, Tensor], K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> dict[str, Tensor]:
        """offsets: the map (B, 2, h, w) (metres, confidence logit). Returns "total", "offset" and
        "confidence" (each unweighted, averaged over its cells)."""
        offset, metres_per_width, confident, trained = lateral_offset_targets(
            targets, K, T_lane_cam, image_size, tuple(offsets.shape[-2:]), self.max_offset, self.max_distance
        )
        predicted = offsets.float()
        error = (predicted[:, 0] - offset) * metres_per_width
        offset_loss = (F.smooth_l1_loss(error, torch.zeros_like(error), reduction="none", beta=0.1) * confident).sum()
        offset_loss = offset_loss / confident.sum().clamp_min(1.0)
        bce = F.binary_cross_entropy_with_logits(predicted[:, 1], confident, reduction="none")
        confidence_loss = (bce * trained).sum() / trained.sum().clamp_min(1)
        total = self.offset_weight * offset_loss + self.confidence_weight * confidence_loss
        return {"total": total, "offset": offset_loss, "confidence": confidence_loss}
