"""Bi-level feature aggregation (BLFA, Bi²Lane §III-C, eq. 7-11), for one direction's lane-feature set.

- Point level (eq. 7-8): the k-th point of each current lane feature attends to the k-th point
  of the same anchor in the N history frames (a Transformer decoder layer: cross-attention, then
  a feed-forward layer, each with a residual). Padded history frames are masked out; a sample
  without any real history frame keeps its current feature.
- Line level (eq. 9-10): the M points of each lane attend to one another (self-attention, then a
  feed-forward layer, residuals as above).
``level`` picks what runs (Table IV): "point", "line", "bilevel" (both, in this order) or "none"
(the lane feature of the current frame as it is, Table III's "+BDTR" without BLFA). The two
directions' results are concatenated by the detector (eq. 11).

The paper is silent on positional information; here the history keys carry a learned embedding
of their age (frames back) and the points of a line a learned embedding of their index k, so
that attention can tell frames and points apart. Post-norm layers as in Anchor3DLane-T's
temporal fusion (nn.TransformerDecoderLayer).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from lanelab.models.bi2lane.single_query_attention import single_query_attention

LEVELS = ("none", "point", "line", "bilevel")


class AttentionLayer(nn.Module):
    """Post-norm attention + feed-forward layer: x = norm(q + attn(q, k, v)); x = norm(x + ffn(x))."""

    def __init__(self, embed_dim: int, num_heads: int, ffn_dim: int, dropout: float) -> None:
        super().__init__()
        self.attention = nn.MultiheadAttention(embed_dim, num_heads, dropout=dropout, batch_first=True)
        self.ffn = nn.Sequential(nn.Linear(embed_dim, ffn_dim), nn.ReLU(inplace=True), nn.Dropout(dropout),
                                 nn.Linear(ffn_dim, embed_dim))  # fmt: skip
        self.norm1, self.norm2 = nn.LayerNorm(embed_dim), nn.LayerNorm(embed_dim)
        self.dropout = nn.Dropout(dropout)

    def forward(
        self, query: Tensor, key: Tensor, value: Tensor, key_padding_mask: Tensor | None = None,
        key_offset: Tensor | None = None,
    ) -> Tensor:  # fmt: skip
        """query (..., Q, C), key / value (..., S, C), key_padding_mask (..., S) bool (True: ignored),
        key_offset (S, C) added to the keys. More than one query: one sample dimension only."""
        if query.shape[-2] == 1:  # the point level: the same result without projecting the S keys
            attended = single_query_attention(self.attention, query, key, value, key_padding_mask, key_offset)
        else:
            key = key if key_offset is None else key + key_offset.to(key.dtype)
            attended, _ = self.attention(query, key, value, key_padding_mask=key_padding_mask, need_weights=False)
        x = self.norm1(query + self.dropout(attended))
        return self.norm2(x + self.dropout(self.ffn(x)))


class BiLevelAggregation(nn.Module):
    """embed_dim C, num_points M, max_history: the most history frames N (the age embedding's
    size); level: one of LEVELS; num_heads, ffn_dim, dropout of each attention layer."""

    def __init__(
        self, embed_dim: int, num_points: int, max_history: int, level: str, num_heads: int, ffn_dim: int,
        dropout: float,
    ) -> None:  # fmt: skip
        super().__init__()
        if level not in LEVELS:
            raise ValueError(f"aggregation must be one of {LEVELS}, got {level!r}")
        self.level = level
        self.point = self.line = None
        if level in ("point", "bilevel") and max_history > 0:
            self.point = AttentionLayer(embed_dim, num_heads, ffn_dim, dropout)
            self.age = nn.Parameter(torch.randn(max_history + 1, embed_dim) * 0.02)  # 0: the current frame
        if level in ("line", "bilevel"):
            self.line = AttentionLayer(embed_dim, num_heads, ffn_dim, dropout)
            self.index = nn.Parameter(torch.randn(num_points, embed_dim) * 0.02)

    def forward(self, current: Tensor, history: Tensor, history_valid: Tensor, oldest_first: bool = False) -> Tensor:
        """current (B, A, M, C): the current frame's lane features; history (B, A, M, N, C): the
        history frames', newest first (``oldest_first``: the other way round), any strides;
        history_valid (B, N) bool, in the history's order. Returns (B, A, M, C)."""
        lanes = current
        if self.point is not None and history.shape[3] > 0:
            lanes = self._point_level(lanes, history, history_valid, oldest_first)
        if self.line is not None:
            B, A, M, C = lanes.shape
            tokens = lanes.reshape(B * A, M, C)
            positioned = tokens + self.index.to(tokens.dtype)
            lanes = self.line(positioned, positioned, tokens).reshape(B, A, M, C)  # eq. 9-10
        return lanes

    def _point_level(self, current: Tensor, history: Tensor, history_valid: Tensor, oldest_first: bool) -> Tensor:
        """Eq. 7-8: each point's query against the same point of every history frame."""
        N = history.shape[3]
        if N >= self.age.shape[0]:
            built = self.age.shape[0] - 1
            raise ValueError(f"{N} history frames, but the point-level aggregation was built for {built}")
        ages = self.age[1 : N + 1].flip(0) if oldest_first else self.age[1 : N + 1]  # the keys' order is the history's
        query = (current + self.age[0].to(current.dtype)).unsqueeze(-2)  # (B, A, M, 1, C)
        any_valid = history_valid.any(-1)  # (B,)
        # A sample without real history attends to its padding instead (a defined softmax), then keeps its query.
        mask = (~history_valid & any_valid[:, None])[:, None, None, :]  # (B, 1, 1, N)
        fused = self.point(query, history, history, mask, key_offset=ages)[..., 0, :]
        return torch.where(any_valid[:, None, None, None], fused, current)
