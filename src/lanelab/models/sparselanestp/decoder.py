"""Transformer decoder: L layers of STA -> DCA -> FFN with iterative control point refinement.

One layer (eq. 3-4 and the FFN after them), post-norm as in LATR / Deformable DETR:
    Q = LN(Q + STA(Q, PE(P), P, memory))       spatio-temporal attention (or global self-attention)
    Q = LN(Q + DCA(Q + PE(P), P_3D, image))    deformable cross-attention around re-projected P
    Q = LN(Q + FFN(Q))
The query positional encoding PE(P) is that of the points the layer starts from, recomputed
every layer as the points move (eq. 11 for memory queries; the same encoding for current ones).
After each layer the shared head refines the control points and classifies the lines. As in
LATR / Deformable DETR, the points a layer starts from are detached, so each layer learns a
correction rather than back-propagating through all the earlier ones; only the initial points
receive the gradient of the first layer's refinement, which trains the initial point MLP.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from lanelab.models.parts.heads import LaneHead
from lanelab.models.sparselanestp.deformable_attention import DeformableCrossAttention
from lanelab.models.sparselanestp.lateral_search import LateralSearch
from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.positional_encoding import PointPositionalEncoding


class DecoderLayer(nn.Module):
    """embed_dim C; ffn_dim: hidden width of the FFN; dropout on the three residual branches;
    self_attention: a SpatioTemporalAttention; cross_attention: a DeformableCrossAttention."""

    def __init__(
        self,
        embed_dim: int,
        ffn_dim: int,
        dropout: float,
        self_attention: nn.Module,
        cross_attention: DeformableCrossAttention,
    ) -> None:
        super().__init__()
        self.self_attention = self_attention
        self.cross_attention = cross_attention
        self.ffn = nn.Sequential(
            nn.Linear(embed_dim, ffn_dim), nn.ReLU(inplace=True), nn.Dropout(dropout), nn.Linear(ffn_dim, embed_dim)
        )
        self.norms = nn.ModuleList(nn.LayerNorm(embed_dim) for _ in range(3))
        self.dropout = nn.Dropout(dropout)

    def forward(
        self,
        queries: Tensor,
        query_pos: Tensor,
        points: Tensor,
        memory: MemoryState | None,
        memory_pos: Tensor | None,
        features: Sequence[Tensor],
        K: Tensor,
        T_lane_cam: Tensor,
        image_size: tuple[int, int],
        line_mask: Tensor | None = None,
    ) -> Tensor:
        """queries, query_pos (B, N, M, C); points (B, N, M, 4) metres; memory / memory_pos
        (B, K, C) or None; features, K, T_lane_cam, image_size: see DeformableCrossAttention;
        line_mask (B, N) bool, False for padded lines (None: all real). Returns (B, N, M, C)."""
        B, N, M, C = queries.shape
        attended = self.self_attention(queries, query_pos, points, memory, memory_pos, line_mask)
        queries = self.norms[0](queries + self.dropout(attended))
        sampled = self.cross_attention(
            (queries + query_pos).flatten(1, 2), points[..., :3].flatten(1, 2), features, K, T_lane_cam, image_size
        )
        queries = self.norms[1](queries + self.dropout(sampled.view(B, N, M, C)))
        return self.norms[2](queries + self.dropout(self.ffn(queries)))


class LaneDecoder(nn.Module):
    """layers: the L DecoderLayers; head: the LaneHead shared by all of them;
    positional_encoding: the PointPositionalEncoding of queries and memory; searches: one
    LateralSearch per layer, which moves each refined control point across the road onto the
    marking it finds (models.sparselanestp.lateral_search), or None."""

    def __init__(
        self,
        layers: Sequence[DecoderLayer],
        head: LaneHead,
        positional_encoding: PointPositionalEncoding,
        searches: Sequence[LateralSearch] | None = None,
    ) -> None:
        super().__init__()
        self.layers = nn.ModuleList(layers)
        self.head = head
        self.positional_encoding = positional_encoding
        self.searches = None if searches is None else nn.ModuleList(searches)

    def forward(
        self,
        queries: Tensor,
        logits: Tensor,
        memory: MemoryState | None,
        features: Sequence[Tensor],
        K: Tensor,
        T_lane_cam: Tensor,
        image_size: tuple[int, int],
        line_mask: Tensor | None = None,
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Run all layers.

        queries: 0Q (B, N, M, C); logits: initial pre-sigmoid (x, z, v) (B, N, M, 3);
        memory: the memory queue's state, or None without temporal fusion; line_mask (B, N) bool,
        False for padded lines, which no line attends to (None: all real).
        Returns per-layer control points (L, B, N, M, 4) and class logits (L, B, N, K + 1),
        and the last layer's queries (B, N, M, C) (what the memory queue stores).
        """
        memory_pos = None
        if memory is not None:
            memory_pos = self.positional_encoding(self.head.normalise(memory.points))
        all_points, all_classes = [], []
        points = self.head.control_points(logits)
        for index, layer in enumerate(self.layers):
            if index > 0:  # the points of the last layer's logits, detached as they are
                logits, points = logits.detach(), all_points[-1].detach()
            query_pos = self.positional_encoding(self.head.normalise(points))
            queries = layer(queries, query_pos, points, memory, memory_pos, features, K, T_lane_cam, image_size, line_mask)
            logits = self.head.refine(queries, logits)
            if self.searches is not None:
                points = self.head.control_points(logits)
                logits = self.head.shift_x(logits, self.searches[index](queries, points, features[0], K, T_lane_cam, image_size))
            all_points.append(self.head.control_points(logits))
            all_classes.append(self.head.classify(queries))
        return torch.stack(all_points), torch.stack(all_classes), queries
