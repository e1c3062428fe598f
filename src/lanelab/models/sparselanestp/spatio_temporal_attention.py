"""Spatio-temporal attention (STA), SparseLaneSTP §3.3, Fig. 3 and supplementary C.

Every query (line i, control point m) attends, in ONE softmax, to the union of its SLA, PNA
and TCA keys (:mod:`lanelab.models.sparselanestp.sta_masks`): the paper implements STA as a single masked
attention layer, so the three relations compete for the same attention mass. Queries and keys
carry their positional encodings (eq. 11), values do not (DETR / LATR / StreamPETR):
    current keys  = Q + PE(P),      current values = Q
    memory keys   = Q_mem + PE(P_mem→t),   memory values = Q_mem
The module returns the attention output after its projection; the decoder layer adds the
residual and the LayerNorm (post-norm, as LATR's self-attention block).

Three implementations (``impl``) of the same layer, and a choice between two of them:
- "sparse": cost follows the active relations, using the structure of the masks:
  SLA is block-diagonal, one M x M attention per line. PNA and TCA keys lie on lines of M
  points (the current lines; the memory's stored lines) near the query's own point index: a
  normal plane cuts a parallel line near the same y, and a static lane seen from a few metres
  back is shifted by a point or two. So query row m scores a band of W point indices around m
  on every line, W = 2·reach + 1 with reach the largest |n - m| among the actual neighbours:
  exact for any geometry, narrow where lanes run alike (W = 3 for PNA on parallel lanes, at
  most 2M - 1). The scores are batched matmuls per query row; the masks keep the exact keys.
  The SLA block and the band's W point slots of PNA and TCA are chunks of ONE masked softmax,
  computed chunk by chunk with a running maximum (as flash attention does), so only one
  chunk's logits exist at a time. No (N·M)^2 matrix and no per-query copy of key vectors:
  gathering the ~108 keys of every query, as (B, N·M, 108, C), moves more memory than the
  whole dense attention matrix at C = 256.
- "dense": the reference; the full boolean mask over [N·M queries ‖ K memory tokens] and
  masked scaled-dot-product attention (torch's fused kernel where the device has one).
- "auto": "dense" on a GPU, "sparse" elsewhere, per call. The sparse path's chunked softmax is
  dozens of small kernels where torch's fused masked kernel is one: on an H200 the fused kernel
  was 2x faster in inference and 3x in training, on a CPU the sparse path 1.3x faster and
  smaller (benchmarks/RESULTS.md, bench_sta.py).
- "global": plain self-attention over all N·M queries, no memory, no masks (LATR's decoder;
  the single-frame baseline). use_sla / use_pna / use_tca are ignored.
A query without any active key (every key padded) gets a zero attention output.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.sta_masks import Neighbours, find_neighbours, neighbour_masks

IMPLEMENTATIONS = ("auto", "sparse", "dense", "global")


class SpatioTemporalAttention(nn.Module):
    """embed_dim C, num_heads H; num_neighbors: PNA points per other line (2); m_tca: TCA
    memory points per query (10); use_sla / use_pna / use_tca: the relations (Table 2);
    dropout: on the attention weights; impl: "auto", "sparse", "dense" or "global" (module doc)."""

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
        impl: str = "auto",
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
        self.pna_tie_margin = 0.0  # metres; set for export (deploy.explicit_state.settle_ties)
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
        positioned = queries + query_pos
        q = self._split_heads(self.q_proj(positioned))  # (B, H, N, M, d)
        k = self._split_heads(self.k_proj(positioned))
        del positioned
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
                    self.pna_tie_margin,
                )  # fmt: skip
            k_mem = v_mem = None
            if memory is not None:
                keys = memory.embeddings if memory_pos is None else memory.embeddings + memory_pos
                k_mem, v_mem = self.k_proj(keys), self.v_proj(memory.embeddings)  # (B, K, C)
            if neighbours.empty:
                out = torch.zeros_like(q)
            else:
                sparse = self.impl == "sparse" or (self.impl == "auto" and not q.is_cuda)
                attend = self._sparse if sparse else self._dense
                out = attend(q, k, v, k_mem, v_mem, neighbours)
        return self.out_proj(out.movedim(1, -2).reshape(B, N, M, C))

    # ------------------------------------------------------------------ paths
    def _sparse(
        self, q: Tensor, k: Tensor, v: Tensor, k_mem: Tensor | None, v_mem: Tensor | None, nb: Neighbours
    ) -> Tensor:
        """q, k, v (B, H, N, M, d); k_mem, v_mem (B, K, C) -> (B, H, N, M, d).

        Works on queries ordered by point row, point-major: (M, B, H, N, d). A chunk scores all
        N queries of a row against the same keys, one bmm per chunk, and the chunks share one
        softmax (:class:`_ChunkedSoftmax`)."""
        B, H, N, M, d = q.shape
        q = q.mul_(d**-0.5)  # the softmax scale applied to the queries (q is this layer's own copy)
        rows = q.permute(3, 0, 1, 2, 4).contiguous()  # (M, B, H, N, d)
        softmax = _ChunkedSoftmax(self._dropout_p())
        if nb.use_sla:  # block-diagonal: the M x M attention of every line
            logits = _bmm(q, k.transpose(-1, -2)).permute(3, 0, 1, 2, 4)  # (M, B, H, N, M)
            mask = nb.line_valid[None, :, None, :, None]  # every point of a real line
            softmax.add(logits, mask, lambda w: _bmm(w.permute(1, 2, 3, 0, 4), v).permute(3, 0, 1, 2, 4))
        if nb.pna_index is not None:  # neighbours on the current lines
            lines = torch.arange(N, device=q.device).repeat_interleave(nb.pna_index.shape[-1])
            index, valid = nb.pna_index.transpose(1, 2).flatten(-2), nb.pna_valid.transpose(1, 2).flatten(-2)
            softmax.add_all(_band_chunks(rows, k, v, lines, index, valid))
        if nb.tca_index is not None:  # nearest memory points, on the stored lines of M points
            k_lines = self._split_heads(k_mem).unflatten(2, (-1, M))  # (B, H, L_mem, M, d)
            v_lines = self._split_heads(v_mem).unflatten(2, (-1, M))
            index, valid = nb.tca_index.transpose(1, 2), nb.tca_valid.transpose(1, 2)
            softmax.add_all(_band_chunks(rows, k_lines, v_lines, index // M, index % M, valid))
        return softmax.result().permute(1, 2, 3, 0, 4)

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
        """(B, ..., C) -> (B, H, ..., C / H), contiguous (batched matmuls over heads take it as is)."""
        return x.unflatten(-1, (self.num_heads, -1)).movedim(-2, 1).contiguous()


# exp() of arguments below this takes a slow path on CPUs (several times slower); the weight it
# gives a masked key, 1.6e-38 against 1 for the row's maximum, is zero to float precision.
EXP_FLOOR = -87.0


class _ChunkedSoftmax:
    """One softmax attention over keys that arrive in chunks (the running-maximum form of
    flash attention): only one chunk's logits exist at a time, and no key vector is copied
    more than once. Masked keys get the dtype's lowest value (not -inf: no inf - inf arises),
    so a query without any active key attends to every key and then outputs zero, like
    _masked_sdpa."""

    def __init__(self, dropout: float) -> None:
        self.dropout = dropout
        self.max: Tensor | None = None  # (M, B, H, N, 1) running maximum (no gradient: softmax is shift-invariant)
        self.total: Tensor | None = None  # (M, B, H, N, 1) running sum of exp(logit - max)
        self.out: Tensor | None = None  # (M, B, H, N, d) running weighted sum of the values
        self.has_key: Tensor | None = None  # (M or 1, B, 1, N, 1)

    def add(self, logits: Tensor, mask: Tensor, weighted_sum: Callable[[Tensor], Tensor]) -> None:
        """logits (M, B, H, N, a), a fresh tensor (changed in place); mask broadcastable to it
        with 1 head; weighted_sum maps weights (M, B, H, N, a) to their values' sum (M, B, H, N, d)."""
        logits = logits.masked_fill_(~mask, torch.finfo(logits.dtype).min)
        new_max = logits.detach().amax(-1, keepdim=True)
        if self.max is not None:
            new_max = torch.maximum(self.max, new_max)
        weights = logits.sub_(new_max).clamp_min_(EXP_FLOOR).exp_()
        total = weights.sum(-1, keepdim=True)
        out = weighted_sum(F.dropout(weights, self.dropout, self.dropout > 0))
        has_key = mask.any(-1, keepdim=True)
        if self.max is not None:  # rescale what came before to the new maximum (in place: no copies)
            rescale = (self.max - new_max).clamp_min_(EXP_FLOOR).exp_()
            total, out, has_key = total.add_(self.total.mul_(rescale)), out.add_(self.out.mul_(rescale)), has_key | self.has_key
        self.max, self.total, self.out, self.has_key = new_max, total, out, has_key

    def add_all(self, chunks: Iterator[tuple[Tensor, Tensor, Callable[[Tensor], Tensor]]]) -> None:
        for chunk in chunks:
            self.add(*chunk)
            del chunk  # before the next chunk is computed: one chunk alive at a time

    def result(self) -> Tensor:
        """(M, B, H, N, d) the attention output; zero for queries without a key."""
        return self.out / self.total * self.has_key


def _band_chunks(
    rows: Tensor, keys: Tensor, values: Tensor, lines: Tensor, points: Tensor, valid: Tensor
) -> Iterator[tuple[Tensor, Tensor, Callable[[Tensor], Tensor]]]:
    """Attention chunks over keys that lie on lines of M points, near the query's point index.

    rows (M, B, H, N, d): the queries, row m holding point m of every line; keys, values
    (B, H, L, M, d): L lines of M points; lines, points, valid (B, M, N, k) (lines may
    broadcast): line and point index of the keys of query (line i, point m).
    With reach = max |point - m| over the valid keys, row m looks at the W = 2·reach + 1 points
    m - reach ... m + reach of every line: exact for any geometry, and narrow (W = 3 for
    parallel lanes) where lines run alike. One chunk per window slot o: every row m scores
    point m - reach + o of all L lines. The keys are laid out point-major, (M, B, H, L, d),
    with reach zero points before and after (masked), so a slot's keys are the slice
    [o, o + M) of that tensor: a view, nothing gathered.
    Yields logits (M, B, H, N, L), mask (M, B, 1, N, L) and the weights -> output map.
    """
    M, L = rows.shape[0], keys.shape[2]
    row = torch.arange(M, device=rows.device)[:, None, None]  # broadcasts over (M, N, k)
    slot = (points - row).masked_fill(~valid, 0)
    reach = int(slot.abs().amax()) if slot.numel() else 0
    width = 2 * reach + 1
    # Key (l, point) of row m sits in slot (point - m + reach) · L + l; invalid keys in a spare slot.
    slot = ((slot + reach) * L + lines).masked_fill(~valid, width * L)
    mask = torch.zeros(*slot.shape[:-1], width * L + 1, dtype=torch.bool, device=rows.device)
    mask = mask.scatter_(-1, slot, True)[..., :-1].unflatten(-1, (width, L))  # (B, M, N, W, L)
    mask = mask.permute(3, 1, 0, 2, 4)[:, :, :, None]  # (W, M, B, 1, N, L)
    keys, values = _point_major(keys, reach), _point_major(values, reach)  # (M + 2·reach, B, H, L, d)
    for o in range(width):
        k_o, v_o = keys[o : o + M], values[o : o + M]  # (M, B, H, L, d): point m - reach + o of row m
        yield _bmm(rows, k_o.transpose(-1, -2)), mask[o], lambda w, v_o=v_o: _bmm(w, v_o)


def _point_major(x: Tensor, pad: int) -> Tensor:
    """(B, H, L, M, d) -> (M + 2·pad, B, H, L, d), contiguous, zero points before and after."""
    out = x.new_zeros(x.shape[3] + 2 * pad, *x.shape[:3], x.shape[4])
    out[pad : pad + x.shape[3]] = x.permute(3, 0, 1, 2, 4)
    return out


def _bmm(a: Tensor, b: Tensor) -> Tensor:
    """a (..., n, k) @ b (..., k, m) -> (..., n, m), as one bmm over the leading dimensions:
    unlike matmul, bmm takes a transposed operand as it is instead of copying it."""
    batch = a.shape[:-2]
    return torch.bmm(a.reshape(-1, *a.shape[-2:]), b.reshape(-1, *b.shape[-2:])).view(*batch, a.shape[-2], b.shape[-1])
