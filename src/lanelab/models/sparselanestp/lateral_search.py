"""Lateral search: where is the marking across each control point? (a soft-argmax over the road)

Not in SparseLaneSTP or LATR; added for issue "The detectors must learn", off by default
(``lateral_search: null``) since it measured no help on held-out drives (benchmarks/RESULTS.md,
ninth round of the learning diagnostics); checkpoints trained with it still build.

The decoder's heads refine a control point's x from its query alone (eq. 5), which says what
the deformable cross-attention read but not where that was relative to the point: the features
carry absolute positions (the ground encoding) and the point's own position never enters the
query, so a small model trained from scratch does not learn to move a point onto the marking
it sees (measured: the refinements left the near range no better than the initial points).
Row-anchor lane detectors (UFLD) and Anchor3DLane's offset regression localise by what lies
*across* a lane instead; this module does the same in 3D.

For every control point (x, y, z) it places K candidates at (x + δ_k, y, z) on the road, with
offsets δ_k spread evenly over ±``search_range`` metres, projects them into the image, reads
the feature map there (bilinear), and scores each by the dot product of its feature with a
projection of the query (plus a learned bias per offset). The softmax over the candidates
in the image gives the expected offset Σ p_k δ_k, in metres, which the decoder adds to x. Its
gradient trains the scores directly (the loss pulls the expectation onto the marking), so
what the backbone must learn is "is there a marking here", not a coordinate regression.
Candidates that fall outside the image or behind the camera are left out; a point none of
whose candidates is in the image is not moved.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import image_extent, project_lane_points


class LateralSearch(nn.Module):
    """embed_dim C; num_candidates K (odd: one at the point itself); search_range: metres of
    the outermost candidates either side of the point."""

    def __init__(self, embed_dim: int, num_candidates: int, search_range: float) -> None:
        super().__init__()
        if num_candidates < 2 or search_range <= 0:
            raise ValueError(f"lateral search needs >= 2 candidates and a positive range, got {num_candidates}, {search_range}")
        self.register_buffer("offsets", torch.linspace(-search_range, search_range, num_candidates), persistent=False)
        self.value_proj = nn.Conv2d(embed_dim, embed_dim, 1)
        self.query_proj = nn.Linear(embed_dim, embed_dim)
        self.bias = nn.Parameter(torch.zeros(num_candidates))

    def forward(
        self, queries: Tensor, points: Tensor, feature: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> Tensor:
        """queries (B, N, M, C); points (B, N, M, >= 3) lane frame, metres; feature (B, C, H_f, W_f)
        covering the image of K (B, 3, 3), image_size (H, W) pixels; T_lane_cam (B, 4, 4).
        Returns the lateral shifts (B, N, M), metres (float32 at least)."""
        B, N, M, C = queries.shape
        dtype = torch.promote_types(points.dtype, torch.float32)  # pixel positions need more than bf16
        offsets = self.offsets.to(dtype)
        candidates = points[..., None, :3].to(dtype).expand(B, N, M, len(offsets), 3).clone()
        candidates[..., 0] += offsets
        with torch.autocast(points.device.type, enabled=False):
            uv, _, in_front = project_lane_points(candidates.view(B, -1, 3), K.to(dtype), T_lane_cam.to(dtype))
        unit = uv / image_extent(image_size, uv.dtype, uv.device)
        inside = in_front & (unit >= 0).all(-1) & (unit < 1).all(-1)  # (B, N M K)
        grid = torch.where(inside[..., None], 2 * unit - 1, torch.zeros_like(unit))[:, :, None]  # (B, N M K, 1, 2)
        value = self.value_proj(feature)
        sampled = F.grid_sample(value.to(dtype), grid, align_corners=False)[..., 0]  # (B, C, N M K)
        sampled = sampled.transpose(1, 2).reshape(B, N, M, len(offsets), C)
        probe = self.query_proj(queries).to(dtype)[..., None, :]  # (B, N, M, 1, C)
        scores = (sampled * probe).sum(-1) / math.sqrt(C) + self.bias.to(dtype)
        inside = inside.view(B, N, M, len(offsets))
        weights = scores.masked_fill(~inside, float("-inf")).softmax(-1).nan_to_num(0.0)  # none inside: all 0
        return (weights * offsets).sum(-1)
