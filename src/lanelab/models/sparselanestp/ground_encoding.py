"""3D ground positional encoding of image features (LATR's ground PE, with a fixed flat ground).

The deformable cross-attention reads image features at and around the re-projected control
points; a plain CNN feature says what is there, not where it lies on the road. As LATR does
(its "dynamic 3D ground positional embedding"; SparseLaneSTP is silent and follows LATR), every
feature cell is tagged with the 3D point where its pixel's ray meets the ground, so that what a
query reads carries the position of the marking it found, in metres of the lane frame.
Simplification: the ground is the plane z = 0 of the lane frame (LATR also regresses a plane
per layer). Cells above the horizon meet no ground; they get the encoding of visibility 0.

The point is encoded like the control points: normalised by the head's ranges, then the
sinusoid + MLP encoding of :class:`PointPositionalEncoding` (its own weights).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from lanelab.geometry import cell_centres, intersect_ground
from lanelab.models.parts.heads import normalise_points, point_normaliser
from lanelab.models.sparselanestp.positional_encoding import PointPositionalEncoding

# Normalised coordinates are clamped here: cells near the horizon meet the ground kilometres away.
_NORMALISED_LIMITS = (-1.0, 2.0)


class GroundPositionalEncoding(nn.Module):
    """embed_dim C; x_range, y_range, z_range: (start, end) metres that map to [0, 1] (the
    head's, as for the control points)."""

    def __init__(
        self,
        embed_dim: int,
        x_range: tuple[float, float],
        y_range: tuple[float, float],
        z_range: tuple[float, float],
    ) -> None:
        super().__init__()
        self.register_buffer("normaliser", point_normaliser(x_range, y_range, z_range), persistent=False)
        self.encoding = PointPositionalEncoding(embed_dim)

    def forward(
        self, features: Sequence[Tensor], K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> list[Tensor]:
        """features: maps (B, C, H_l, W_l) covering the whole image (H, W) = image_size, pixels
        of K (B, 3, 3); T_lane_cam (B, 4, 4). Returns the maps plus their encodings, same shapes."""
        return [feature + self._encoding(feature, K, T_lane_cam, image_size) for feature in features]

    def _encoding(self, feature: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]) -> Tensor:
        B, C, H_l, W_l = feature.shape
        dtype = torch.promote_types(feature.dtype, torch.float32)  # pixel geometry in at least float32
        uv = cell_centres((H_l, W_l), image_size, dtype, feature.device).expand(B, -1, -1)
        with torch.autocast(feature.device.type, enabled=False):
            points, on_ground = intersect_ground(uv, K.to(dtype), T_lane_cam.to(dtype))
        points = torch.cat([points.nan_to_num(0.0), on_ground[..., None].to(dtype)], -1)  # (B, H_l W_l, 4)
        normalised = normalise_points(points, self.normaliser).clamp(*_NORMALISED_LIMITS)
        normalised = torch.cat([normalised[..., :3] * points[..., 3:], points[..., 3:]], -1)
        encoding = self.encoding(normalised.to(feature.dtype))  # (B, H_l W_l, C)
        return encoding.transpose(1, 2).reshape(B, C, H_l, W_l)
