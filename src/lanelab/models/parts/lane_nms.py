"""Lane non-maximum suppression (Anchor3DLane's NMS, with a lateral distance for the overlap).

Needed where several lines may be trained on one lane (``HungarianMatcher(positive_distance=...)``,
Anchor3DLane's one-to-many assignment): neighbouring lines then both find that lane, and only
the more confident one should be reported. Two lanes are duplicates when their mean lateral
distance over the near range (where both are seen best) is below ``distance`` metres; the
near range only, because a duplicate's far end may drift where the image shows little.
"""

from __future__ import annotations

import torch
from torch import Tensor


def suppress_duplicates(x: Tensor, score: Tensor, valid: Tensor, near: Tensor, distance: float) -> Tensor:
    """x (B, N, S) lateral positions of N lanes at S longitudinal samples; score (B, N);
    valid (B, N) bool, the lanes reported; near (S,) bool, the samples compared.
    Returns valid without every lane that lies within ``distance`` (mean |Δx| over the near
    samples) of a more confident valid lane that is itself kept."""
    weight = near.to(x.dtype)
    gap = ((x[:, :, None] - x[:, None, :]).abs() * weight).sum(-1) / weight.sum().clamp_min(1)  # (B, N, N)
    keep = valid.clone()
    order = score.masked_fill(~valid, -torch.inf).argsort(-1, descending=True)
    for b in range(x.shape[0]):  # greedy, most confident first (N is tens of lines)
        for i in order[b, : int(valid[b].sum())].tolist():
            if keep[b, i]:
                duplicate = gap[b, i] < distance
                duplicate[i] = False
                keep[b] &= ~duplicate
    return keep
