"""Multi-scale deformable cross-attention around lane control points (the DCA of eq. 4).

Deformable DETR's attention (Zhu et al. 2021, eq. 3), with LATR's reference points: each
query's 3D control point is re-projected into the image, and every head samples
``num_points`` locations per feature level around it, at offsets and with weights that the
query predicts. Sampling is bilinear ``F.grid_sample``: one call per level for all queries,
heads and points, so it runs as a handful of large kernels on a GPU.

With ``content_weights`` (not in Deformable DETR) a sample's weight also depends on what it
reads: its attention logit gets the scaled dot product of the sampled value with a projection
of the query, as in ordinary attention. Deformable DETR's weights depend on the query alone, so
its output is a fixed blend of what lies at the sampling locations and cannot say which of them
holds the lane marking; features must learn to encode offsets first, which a small backbone
trained from scratch does not do in a short schedule. With content weights the marking's sample
wins the softmax, and the ground positional encoding it carries says where it is.

A control point that projects outside the image is referenced at the nearest image border
(lanes leave the image at its bottom and sides, and their nearest visible part is there);
one behind the camera gets zero weight on every sample (it reads nothing from the image). A
sampling location that an offset pushes outside the image reads zeros (grid_sample's zero
padding).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import image_extent, project_lane_points


class DeformableCrossAttention(nn.Module):
    """embed_dim C (divisible by num_heads); num_levels: feature maps it reads (the finest
    ``num_levels`` of those passed); num_points: samples per head and level; content_weights:
    also weigh each sample by its content (module doc)."""

    def __init__(
        self, embed_dim: int, num_heads: int, num_levels: int, num_points: int, content_weights: bool = False
    ) -> None:
        super().__init__()
        if embed_dim % num_heads:
            raise ValueError(f"embed_dim {embed_dim} is not divisible by num_heads {num_heads}")
        self.num_heads, self.num_levels, self.num_points = num_heads, num_levels, num_points
        self.sampling_offsets = nn.Linear(embed_dim, num_heads * num_levels * num_points * 2)
        self.attention_weights = nn.Linear(embed_dim, num_heads * num_levels * num_points)
        self.value_proj = nn.Linear(embed_dim, embed_dim)
        self.output_proj = nn.Linear(embed_dim, embed_dim)
        self.content_proj = nn.Linear(embed_dim, embed_dim) if content_weights else None
        self._init_weights()

    def _init_weights(self) -> None:
        # Deformable DETR's initialisation: offsets start on a ring of head-specific directions,
        # point k at distance k + 1 (in pixels of each level); weights start uniform.
        nn.init.zeros_(self.sampling_offsets.weight)
        angles = torch.arange(self.num_heads, dtype=torch.float32) * (2 * math.pi / self.num_heads)
        ring = torch.stack([angles.cos(), angles.sin()], -1)
        ring = ring / ring.abs().max(-1, keepdim=True).values
        ring = ring[:, None, None, :].repeat(1, self.num_levels, self.num_points, 1)
        ring = ring * torch.arange(1, self.num_points + 1, dtype=torch.float32)[None, None, :, None]
        with torch.no_grad():
            self.sampling_offsets.bias.copy_(ring.flatten())
        nn.init.zeros_(self.attention_weights.weight)
        nn.init.zeros_(self.attention_weights.bias)
        for linear in (self.value_proj, self.output_proj):
            nn.init.xavier_uniform_(linear.weight)
            nn.init.zeros_(linear.bias)

    def forward(
        self,
        queries: Tensor,
        points: Tensor,
        features: Sequence[Tensor],
        K: Tensor,
        T_lane_cam: Tensor,
        image_size: tuple[int, int],
    ) -> Tensor:
        """Attend from queries to the image around their control points.

        queries: (B, Q, C), positional encoding already added. points: (B, Q, 3) lane frame,
        metres. features: >= num_levels maps (B, C, H_l, W_l), finest first, each covering the
        whole image. K: (B, 3, 3); T_lane_cam: (B, 4, 4); image_size: (H, W) of the image K
        refers to, pixels. Returns (B, Q, C).
        """
        B, Q, C = queries.shape
        h, L, P = self.num_heads, self.num_levels, self.num_points
        reference, visible = self._reference_points(points, K, T_lane_cam, image_size)  # (B,Q,2), (B,Q)

        offsets = self.sampling_offsets(queries).view(B, Q, h, L, P, 2)
        logits = self.attention_weights(queries).view(B, Q, h, L * P)

        sampled = []
        for level, feature in enumerate(features[:L]):
            H_l, W_l = feature.shape[-2:]
            # Offsets are in pixels of this level; locations in [0, 1] image coordinates.
            size = image_extent((H_l, W_l), offsets.dtype, offsets.device)
            locations = reference[:, :, None, None, :] + offsets[:, :, :, level] / size  # (B,Q,h,P,2)
            grid = (2 * locations - 1).permute(0, 2, 1, 3, 4).reshape(B * h, Q, P, 2)
            value = self.value_proj(feature.flatten(2).transpose(1, 2))  # (B, H_l W_l, C)
            value = value.transpose(1, 2).reshape(B * h, C // h, H_l, W_l)
            # Sampling in the wider dtype (as CUDA autocast does): a bf16 grid would be off by
            # up to a pixel. align_corners=False: -1 and 1 are the outer edges of the border
            # pixels, the pixel-area convention of lanelab.geometry.camera.
            dtype = torch.promote_types(value.dtype, grid.dtype)
            sampled.append(F.grid_sample(value.to(dtype), grid.to(dtype), padding_mode="zeros", align_corners=False))
        samples = torch.cat(sampled, dim=-1)  # (B h, C/h, Q, L P)

        logits = logits.permute(0, 2, 1, 3).reshape(B * h, 1, Q, L * P).to(samples.dtype)
        if self.content_proj is not None:  # + how well each sample's content answers the query
            probe = self.content_proj(queries).view(B, Q, h, C // h).permute(0, 2, 3, 1).reshape(B * h, C // h, Q, 1)
            logits = logits + (probe.to(samples.dtype) * samples).sum(1, keepdim=True) / math.sqrt(C // h)
        weights = logits.softmax(-1) * visible.repeat_interleave(h, 0)[:, None, :, None].to(samples.dtype)
        out = (samples * weights).sum(-1)  # (B h, C/h, Q)
        out = out.view(B, C, Q).transpose(1, 2)
        return self.output_proj(out)

    @staticmethod
    def _reference_points(
        points: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> tuple[Tensor, Tensor]:
        """Project points (B, Q, 3) -> normalised image coordinates (B, Q, 2) in [0, 1], clamped
        to the image, and a (B, Q) mask of those in front of the camera."""
        # At least float32, even under bf16 autocast: pixel positions need more than 8 mantissa bits.
        dtype = torch.promote_types(points.dtype, torch.float32)
        with torch.autocast(points.device.type, enabled=False):
            uv, _, in_front = project_lane_points(points.to(dtype), K.to(dtype), T_lane_cam.to(dtype))
        scale = image_extent(image_size, uv.dtype, uv.device)
        # Points behind the camera get a harmless finite location; their weights are zero anyway.
        reference = torch.where(in_front[..., None], uv / scale, torch.full_like(uv, 0.5)).clamp(0.0, 1.0)
        return reference.to(points.dtype), in_front
