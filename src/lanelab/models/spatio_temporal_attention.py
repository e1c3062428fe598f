"""Spatio-temporal attention (STA), SparseLaneSTP §3.3, Fig. 3 and supplementary C.

Every query (line i, control point m) attends, in ONE softmax, to the union of its SLA, PNA
and TCA keys (:mod:`lanelab.models.sta_masks`): the paper implements STA as a single masked
attention layer, so the three relations compete for the same attention mass. Queries and keys
carry their positional encodings (eq. 11), values do not (DETR / LATR / StreamPETR):
    current keys  = Q + PE(P),      current values = Q
    memory keys   = Q_mem + PE(P_mem→t),   memory values = Q_mem
The module returns the attention output after its projection; the decoder layer adds the
residual and the LayerNorm (post-norm, as LATR's self-attention block).

Three implementations (``impl``) of the same layer:
- "sparse": cost follows the active relations, using the structure of the masks:
  SLA is block-diagonal, one M x M attention per line. PNA and TCA keys lie on lines of M
  points (the current lines; the memory's stored lines) near the query's own point index: a
  normal plane cuts a parallel line near the same y, and a static lane seen from a few metres
  back is shifted by a point or two. So query row m scores a band of W point indices around m
  on every line, W = 2·reach + 1 with reach the largest |n - m| among the actual neighbours:
  exact for any geometry, narrow where lanes run alike (W = 3 for PNA on parallel lanes, at
  most M). The scores are batched matmuls per query row; the masks keep the exact keys.
  SLA, PNA and TCA logits are concatenated and share one masked softmax. No (N·M)^2 matrix
  and no per-query copy of key vectors: gathering the ~108 keys of every query, as
  (B, N·M, 108, C), moves more memory than the whole dense attention matrix at C = 256.
- "dense": the reference; the full boolean mask over [N·M queries ‖ K memory tokens] and
  masked scaled-dot-product attention (torch's fused kernel where the device has one).
- "global": plain self-attention over all N·M queries, no memory, no masks (LATR's decoder;
  the single-frame baseline). use_sla / use_pna / use_tca are ignored.
A query without any active key (every key padded) gets a zero attention output.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.models.memory_queue import MemoryState
from lanelab.models.sta_masks import Neighbours, find_neighbours, neighbour_masks

IMPLEMENTATIONS = ("sparse", "dense", "global")


class SpatioTemporalAttention(nn.Module):
    """embed_dim C, num_heads H; num_neighbors: PNA points per other line (2); m_tca: TCA
    memory points per query (10); use_sla / use_pna / use_tca: the relations (Table 2);
    dropout: on the attention weights; impl: "sparse", "dense" or "global" (module doc)."""

    def __init__(
        self,
        embed_dim: int,
        num_heads: int,
        num_neighbors: int = 2,
        m_tca: int = 10,
        use_sla: bool = True,
        use_pna: bool = True,
        use_tca: bool = True,
        dropout: float = 0.0,
        impl: str = "sparse",
    ) -> None:
        super().__init__()
        if impl not in IMPLEMENTATIONS:
            raise ValueError(f"impl must be one of {IMPLEMENTATIONS}, got {impl!r}")
        if impl != "global" and not (use_sla or use_pna or use_tca):
            raise ValueError("STA needs at least one of use_sla, use_pna, use_tca (or impl='global')")
        if embed_dim % num_heads:
            raise ValueError(f"embed_dim {embed_dim} is not divisible by num_heads {num_heads}")
        self.num_heads, self.num_neighbors, self.m_tca = num_heads, num_neighbors, m_tca
        self.use_sla, self.use_pna, self.use_tca = use_sla, use_pna, use_tca
        self.dropout, self.impl = dropout, impl
        self.q_proj = nn.Linear(embed_dim, embed_dim)
        self.k_proj = nn.Linear(embed_dim, embed_dim)
        self.v_proj = nn.Linear(embed_dim, embed_dim)
        self.out_proj = nn.Linear(embed_dim, embed_dim)

    def forward(
        self,
        queries: Tensor,
        query_pos: Tensor,
        points: Tensor,
        memory: MemoryState | None = None,
        memory_pos: Tensor | None = None,
        line_mask: Tensor | None = None,
    ) -> Tensor:
        """queries, query_pos (B, N, M, C); points (B, N, M, 4) current control points (metres);
        memory: the propagated memory queue (K tokens, lines of M consecutive points as
        MemoryQueue.read orders them) or None; memory_pos (B, K, C), its positional encoding
        (None: zero); line_mask (B, N) bool, False for padded lines.
        Returns the attention output (B, N, M, C) (before residual and norm)."""
        B, N, M, C = queries.shape
        q = self._split_heads(self.q_proj(queries + query_pos))  # (B, H, N, M, d)
        k = self._split_heads(self.k_proj(queries + query_pos))
        v = self._split_heads(self.v_proj(queries))
        if self.impl == "global":
            out = self._global(q, k, v, line_mask)
        else:
            if not self.use_tca or memory is None or memory.points.shape[1] == 0:
                memory = None
            with torch.no_grad():  # neighbour selection is discrete: no gradient through it
                neighbours = find_neighbours(
                    points,
                    None if memory is None else memory.points,
                    None if memory is None else memory.valid,
                    line_mask, self.num_neighbors, self.m_tca, self.use_sla, self.use_pna, self.use_tca,
                )  # fmt: skip
            k_mem = v_mem = None
            if memory is not None:
                keys = memory.embeddings if memory_pos is None else memory.embeddings + memory_pos
                k_mem, v_mem = self.k_proj(keys), self.v_proj(memory.embeddings)  # (B, K, C)
            if neighbours.empty:
                out = torch.zeros_like(q)
            else:
                attend = self._sparse if self.impl == "sparse" else self._dense
                out = attend(q, k, v, k_mem, v_mem, neighbours)
        return self.out_proj(out.movedim(1, -2).reshape(B, N, M, C))

    # ------------------------------------------------------------------ paths
    def _sparse(
        self, q: Tensor, k: Tensor, v: Tensor, k_mem: Tensor | None, v_mem: Tensor | None, nb: Neighbours
    ) -> Tensor:
        """q, k, v (B, H, N, M, d); k_mem, v_mem (B, K, C) -> (B, H, N, M, d).

        Works on queries ordered by point row, (B, H, M, N, d): the banded parts score all N
        queries of a row against the same window of keys, one matmul per row."""
        B, H, N, M, d = q.shape
        rows = (q * d**-0.5).transpose(2, 3).contiguous()  # softmax scale applied to the queries
        # Each relation gives logits (B, H, M, N, a), their mask (B, M, N, a) and the map from
        # its attention weights to the weighted sum of its values (B, H, M, N, d).
        parts = []
        if nb.use_sla:  # block-diagonal: the M x M attention of every line
            sla_logits = (rows.transpose(2, 3) @ k.transpose(-1, -2)).transpose(2, 3)
            sla_mask = nb.line_valid[:, None, :, None].expand(B, M, N, M)
            parts.append((sla_logits, sla_mask, lambda w: (w.transpose(2, 3) @ v).transpose(2, 3)))
        if nb.pna_index is not None:  # neighbours on the current lines
            lines = torch.arange(N, device=q.device).repeat_interleave(nb.pna_index.shape[-1])
            index, valid = nb.pna_index.transpose(1, 2).flatten(-2), nb.pna_valid.transpose(1, 2).flatten(-2)
            parts.append(_band_attention(rows, k, v, lines, index, valid))
        if nb.tca_index is not None:  # nearest memory points, on the stored lines of M points
            k_lines = self._split_heads(k_mem).unflatten(2, (-1, M))  # (B, H, L_mem, M, d)
            v_lines = self._split_heads(v_mem).unflatten(2, (-1, M))
            index, valid = nb.tca_index.transpose(1, 2), nb.tca_valid.transpose(1, 2)
            parts.append(_band_attention(rows, k_lines, v_lines, index // M, index % M, valid))

        sizes = [logits.shape[-1] for logits, _, _ in parts]
        logits = torch.cat([part[0] for part in parts], -1)  # (B, H, M, N, A)
        mask = torch.cat([part[1] for part in parts], -1)  # (B, M, N, A)
        weighted_sums = [part[2] for part in parts]
        del parts  # let the per-part logits go before the softmax allocates its own
        # Like _masked_sdpa: rows without any key attend to everything, then output zero.
        has_key = mask.any(-1, keepdim=True)
        weights = logits.masked_fill_(~(mask | ~has_key)[:, None], -torch.inf).softmax(-1)
        del logits  # not needed by the weighted sums
        weights = F.dropout(weights, self.dropout, self.training).split(sizes, -1)
        out = sum(weighted_sum(part) for weighted_sum, part in zip(weighted_sums, weights))
        return (out * has_key[:, None]).transpose(2, 3)

    def _dense(
        self, q: Tensor, k: Tensor, v: Tensor, k_mem: Tensor | None, v_mem: Tensor | None, nb: Neighbours
    ) -> Tensor:
        """The reference: one masked attention over [current ‖ memory] keys, same shapes as _sparse."""
        B, H, N, M, d = q.shape
        keys, values = k.flatten(2, 3), v.flatten(2, 3)
        if k_mem is not None:
            keys = torch.cat([keys, self._split_heads(k_mem)], dim=2)
            values = torch.cat([values, self._split_heads(v_mem)], dim=2)
        masks = neighbour_masks(nb, N, M, keys.shape[2] - N * M)
        mask = torch.stack(list(masks.values())).any(0)  # (B, N·M, N·M + K)
        return self._masked_sdpa(q.flatten(2, 3), keys, values, mask).view(B, H, N, M, d)

    def _global(self, q: Tensor, k: Tensor, v: Tensor, line_mask: Tensor | None) -> Tensor:
        """Self-attention over all N·M queries; keys of padded lines masked."""
        B, H, N, M, d = q.shape
        q, k, v = q.flatten(2, 3), k.flatten(2, 3), v.flatten(2, 3)
        if line_mask is None:
            out = F.scaled_dot_product_attention(q, k, v, dropout_p=self._dropout_p())
        else:
            key_valid = line_mask.repeat_interleave(M, dim=1)  # (B, N·M)
            out = self._masked_sdpa(q, k, v, key_valid[:, None, :].expand(B, N * M, N * M))
        return out.view(B, H, N, M, d)

    # ---------------------------------------------------------------- helpers
    def _masked_sdpa(self, q: Tensor, k: Tensor, v: Tensor, mask: Tensor) -> Tensor:
        """Masked attention q (B, H, Q, d), k / v (B, H, S, d), mask (B, Q, S) True = attend.
        Rows without a key would be NaN: they attend to everything and are zeroed after."""
        has_key = mask.any(-1, keepdim=True)
        out = F.scaled_dot_product_attention(
            q, k, v, attn_mask=(mask | ~has_key)[:, None], dropout_p=self._dropout_p()
        )
        return out * has_key[:, None]

    def _dropout_p(self) -> float:
        return self.dropout if self.training else 0.0

    def _split_heads(self, x: Tensor) -> Tensor:
        """(B, ..., C) -> (B, H, ..., C / H)."""
        return x.unflatten(-1, (self.num_heads, -1)).movedim(-2, 1)


def _band_attention(
    rows: Tensor, keys: Tensor, values: Tensor, lines: Tensor, points: Tensor, valid: Tensor
) -> tuple[Tensor, Tensor, Callable[[Tensor], Tensor]]:
    """Attention part over keys that lie on lines of M points, near the query's point index.

    rows (B, H, M, N, d): the queries, row m holding point m of every line; keys, values
    (B, H, L, M, d): L lines of M points; lines, points, valid (B, M, N, k) (lines may
    broadcast): line and point index of the keys of query (line i, point m).
    With reach = max |point - m| over the valid keys, row m scores the W = min(2·reach + 1, M)
    points [start(m), start(m) + W) of every line, start(m) = clamp(m - reach, 0, M - W): a
    window that holds [m - reach, m + reach] ∩ [0, M), so the band is exact for any geometry,
    and narrow (W = 3 for parallel lanes) where lines run alike.
    Returns logits (B, H, M, N, W·L), mask (B, M, N, W·L) and the weights -> output map.
    """
    M, L = rows.shape[2], keys.shape[2]
    row = torch.arange(M, device=rows.device)[:, None, None]  # broadcasts over (M, N, k)
    offset = (points - row).abs().masked_fill(~valid, 0)
    reach = int(offset.amax()) if offset.numel() else 0
    width = min(2 * reach + 1, M)
    start = (torch.arange(M, device=rows.device) - reach).clamp(0, M - width)
    window = start[:, None] + torch.arange(width, device=rows.device)  # (M, W)
    # Key (l, n) of row m sits in slot (n - start(m)) · L + l; invalid keys go to a spare slot.
    slot = ((points - start[:, None, None]) * L + lines).masked_fill(~valid, width * L)
    mask = torch.zeros(*slot.shape[:-1], width * L + 1, dtype=torch.bool, device=rows.device)
    mask = mask.scatter_(-1, slot, True)[..., :-1]

    def band(x: Tensor) -> Tensor:  # (B, H, L, M, d) -> (B, H, M, W·L, d): row m's window of keys
        return x.transpose(2, 3).contiguous()[:, :, window].flatten(3, 4)

    k_band, v_band = band(keys), band(values)
    return rows @ k_band.transpose(-1, -2), mask, lambda w: w @ v_band
