"""Multi-head attention of one query over S keys, without projecting the keys and values.

Bi²Lane's point level (eq. 7-8) asks this of every point of every anchor: 4431 anchors x 20
points attend, one query each, to the same point in the N history frames. ``nn.MultiheadAttention``
projects all N keys and values first, 2 N C² multiply-adds per point, and that made the point
level the largest cost growing with N. Both projections are linear, so per head h
    q_h . (W_k,h k + b_k,h)     = (W_k,h^T q_h) . k + const     (the constant cancels in the softmax)
    sum_s p_s (W_v,h v_s + b_v,h) = W_v,h (sum_s p_s v_s) + b_v,h sum_s p_s
and the query is projected back into the key space once instead: 4 C² + 2 S C H per point. The
result is ``nn.MultiheadAttention``'s up to float rounding, with its parameters (checkpoints
load either way) and its dropout on the attention weights.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn


def single_query_attention(
    attention: nn.MultiheadAttention,
    query: Tensor,
    key: Tensor,
    value: Tensor,
    key_padding_mask: Tensor | None = None,
    key_offset: Tensor | None = None,
) -> Tensor:
    """``attention(query, key + key_offset, value, key_padding_mask)[0]`` for one query per sample.

    attention: a batch-first module with one in-projection and biases (the defaults);
    query (..., 1, C); key, value (..., S, C), any leading sample dimensions; key_padding_mask
    broadcastable to (..., S) bool, True: ignored; key_offset (S, C), added to every sample's keys
    (a positional embedding) without the sum being formed. Returns (..., 1, C)."""
    if not (attention._qkv_same_embed_dim and attention.in_proj_bias is not None and attention.bias_k is None):
        raise ValueError("single_query_attention needs nn.MultiheadAttention's default projections (one in_proj, biases)")
    C = query.shape[-1]
    H = attention.num_heads
    D = C // H
    w_q, w_k, w_v = attention.in_proj_weight.chunk(3)
    b_q, _, b_v = attention.in_proj_bias.chunk(3)
    q = F.linear(query[..., 0, :], w_q, b_q).unflatten(-1, (H, D)) * D**-0.5  # (..., H, D)
    q_in_key_space = torch.einsum("...hd,hdc->...hc", q, w_k.view(H, D, C))
    if value is key:  # cast once: under autocast each product would cast the keys (N lanes a point) anew
        key = value = key.to(q_in_key_space.dtype)
    scores = q_in_key_space @ key.transpose(-1, -2)  # (..., H, S)
    if key_offset is not None:
        scores = scores + q_in_key_space @ key_offset.to(scores.dtype).T
    if key_padding_mask is not None:
        scores = scores.masked_fill(key_padding_mask[..., None, :], float("-inf"))
    weights = F.dropout(scores.softmax(-1), attention.dropout, attention.training)
    mixed = weights @ value  # (..., H, C)
    heads = torch.einsum("...hc,hdc->...hd", mixed, w_v.view(H, D, C)) + b_v.view(H, D) * weights.sum(-1, keepdim=True)
    return attention.out_proj(heads.flatten(-2)).unsqueeze(-2)
