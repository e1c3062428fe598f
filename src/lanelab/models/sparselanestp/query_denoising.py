"""Query denoising (DN-DETR, Li et al. 2022; StreamPETR trains its queries this way).

In training, every ground-truth lane also enters the decoder as an extra line: its control
points moved sideways by a random offset and turned by a random angle, its content one learned
embedding (the same for every such line, so that nothing but its points and the image says which
lane it is). The decoder must bring it back onto its lane, and its target is known without
matching: the lane it was made from. That teaches the decoder's refinement to move points
toward what the image shows from the first step, which the matched lines, starting from learned
anchors that a template already fits, learn late or never (issue "Decoders that read the road").

The noised lines run through the decoder apart from the detection's lines (their own pass,
attending to each other and to the memory, never to the matched lines), and each group of
them as its own batch element, so that one group's noise cannot reveal another's. Only in
training; inference never sees them.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from lanelab.geometry import interpolate_in_y


class QueryDenoising(nn.Module):
    """embed_dim C; num_points M; groups R: noised copies of every lane (each its own batch
    element); max_shift: metres, the lateral offset drawn uniformly in ±max_shift; max_angle:
    degrees, the turn drawn uniformly in ±max_angle about the lane's first control point."""

    def __init__(self, embed_dim: int, num_points: int, groups: int, max_shift: float, max_angle: float) -> None:
        super().__init__()
        if groups < 1 or max_shift < 0 or max_angle < 0:
            raise ValueError(
                f"denoising needs groups >= 1 and non-negative noise, got {groups}, {max_shift}, {max_angle}"
            )
        self.content = nn.Parameter(torch.zeros(embed_dim))
        self.groups, self.max_shift, self.max_slope = groups, max_shift, math.tan(math.radians(max_angle))

    def noised_points(self, targets: dict[str, Tensor], y: Tensor) -> tuple[Tensor, Tensor]:
        """targets: gt_y (B, S), gt_x / gt_z / gt_vis (B, G, S), gt_mask (B, G); y (M,) the
        control points' y. Returns noised control points (B R, G, M, 4) = (x, y, z, v), metres,
        group r of sample b at row b R + r, and the lanes' mask (B R, G)."""
        B, G = targets["gt_mask"].shape
        grid, at = targets["gt_y"].float()[:, None].expand(B, G, -1), y.float().expand(B, G, -1)
        # the lanes at the control points' y, held at their end values beyond them (as the targets are)
        lanes = [interpolate_in_y(at, grid, targets[key].float())[0] for key in ("gt_x", "gt_z", "gt_vis")]
        points = torch.stack(lanes, -1).repeat_interleave(self.groups, 0)  # (B R, G, M, 3)
        BR = points.shape[0]
        unit = torch.rand(2, BR, G, 1, device=points.device) * 2 - 1
        shift = unit[0] * self.max_shift + unit[1] * self.max_slope * (y - y[0]).to(points)
        x = points[..., 0] + shift
        ys = y.to(points).expand_as(x)
        noised = torch.stack([x, ys, points[..., 1], points[..., 2]], -1)
        return noised, targets["gt_mask"].repeat_interleave(self.groups, 0)

    def queries(self, point_embedding: Tensor, shape: tuple[int, int]) -> Tensor:
        """The noised lines' content queries (B R, G, M, C): the learned content plus each
        point's embedding (M, C) (the query generator's)."""
        return (self.content + point_embedding).expand(*shape, *point_embedding.shape)
