"""Positional encoding of control points, SparseLaneSTP eq. 11 (Q~ = Q + PE(P)).

The paper encodes "3D geometry and visibility"; its details follow StreamPETR / PETR's
``pos2posemb3d`` + query-embedding MLP: each normalised coordinate u in [0, 1] is scaled by
2π and expanded into num_feats sinusoids sin(2π u / τ^(2i/F)), cos(2π u / τ^(2i/F)) with
temperature τ (10000); the four expansions (x, y, z, v) are concatenated and mapped to the
embedding width by Linear-ReLU-Linear. The MLP learns which frequencies matter, so the same
module serves current queries and propagated memory points (which may leave [0, 1]).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn


class PointPositionalEncoding(nn.Module):
    """embed_dim C; num_feats F sinusoids per coordinate (default C / 2, StreamPETR's 128 for
    C = 256); temperature τ of the frequency ladder."""

    def __init__(self, embed_dim: int, num_feats: int | None = None, temperature: float = 10000.0) -> None:
        super().__init__()
        num_feats = embed_dim // 2 if num_feats is None else num_feats
        if num_feats % 2:
            raise ValueError(f"num_feats must be even (sin/cos pairs), got {num_feats}")
        # Frequencies 2π / τ^(2i/F), one per sin/cos pair.
        exponent = torch.arange(num_feats // 2, dtype=torch.float64) * 2 / num_feats
        self.register_buffer("frequencies", (2 * math.pi / temperature**exponent).float(), persistent=False)
        self.mlp = nn.Sequential(
            nn.Linear(4 * num_feats, embed_dim), nn.ReLU(inplace=True), nn.Linear(embed_dim, embed_dim)
        )

    def forward(self, points: Tensor) -> Tensor:
        """points (..., 4) = (x, y, z, v), x, y, z mapped to [0, 1] by the configured ranges
        (``LaneHead.normalise``), v in [0, 1] -> (..., C)."""
        angles = points[..., :, None] * self.frequencies.to(points)  # (..., 4, F / 2)
        sinusoids = torch.stack([angles.sin(), angles.cos()], dim=-1)  # (..., 4, F / 2, 2)
        return self.mlp(sinusoids.flatten(-3))
