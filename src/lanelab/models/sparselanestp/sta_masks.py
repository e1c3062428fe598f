"""Which keys each query of the spatio-temporal attention sees (SparseLaneSTP §3.3, supp. C.1).

Query (i, m) is control point m of line i. Its keys are the union of
- SLA, same line attention: the M points of line i (itself included);
- PNA, parallel neighbour attention: on every other line j, the ``num_neighbors`` (2) points
  nearest to the plane through the query orthogonal to its curve, so 2 (N - 1) keys;
- TCA, temporal cross-attention: the ``m_tca`` (10) propagated memory points nearest to the
  query in 3D (euclidean).

PNA follows LaneCPP's orthogonal correspondence, as the paper says: the curve's unit tangent t
at the query (derivative of its Catmull-Rom spline at the control point) defines the normal
plane {q : t · (q - p) = 0}; a point q of line j is as near to that plane as |t · (q - p)|.
The two nearest are the two control points of line j around the place where the plane cuts
it; for parallel lines on a common y grid they sit beside the query, for curved or slanted
lines they move along line j with the orthogonal direction.

Keys on padded lines (line_mask False) and invalid memory tokens are never active. The same
:func:`find_neighbours` feeds the sparse attention (which gathers the keys) and
:func:`sta_masks` (the boolean masks of the dense reference and of the tests), so the two
paths attend to exactly the same keys.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from lanelab.runtime.ranking import topk

# Metres per candidate position by which an exported PNA settles near-ties the same way on every
# backend (runtime.ranking, deploy.explicit_state.settle_ties): on near-parallel lines a line's
# points before and after a query lie equally far from its normal plane, up to the lines' tilt
# (measured 1e-4 m on a trained model); its M points lie 5-10 m apart. Training keeps the plain
# nearest (a model trained with the margin scored 5 points lower on the demo's held-out drives).
PNA_TIE_MARGIN_M = 1e-2


@dataclass
class Neighbours:
    """The active keys of every query; B batch, N lines, M points, k = num_neighbors,
    k_t = min(m_tca, K) for K memory tokens. A relation that is switched off is None.

    line_valid: (B, N) bool, line i's points are keys (SLA) / line j's points are keys (PNA).
    pna_index: (B, N, M, N, k) long, point index n on line j of query (i, m)'s neighbours.
    pna_valid: (B, N, M, N, k) bool, False on the query's own line and on padded lines.
    tca_index: (B, N, M, k_t) long, memory token index of query (i, m)'s nearest memory points.
    tca_valid: (B, N, M, k_t) bool, False where fewer than k_t memory tokens are valid.
    """

    line_valid: Tensor
    use_sla: bool
    pna_index: Tensor | None = None
    pna_valid: Tensor | None = None
    tca_index: Tensor | None = None
    tca_valid: Tensor | None = None

    @property
    def empty(self) -> bool:
        """No relation at all (e.g. TCA alone before the memory holds anything)."""
        return not self.use_sla and self.pna_index is None and self.tca_index is None


def curve_tangents(points: Tensor) -> Tensor:
    """Unit tangents (B, N, M, 3) of the Catmull-Rom curves through points (B, N, M, >=3) at
    their control points (the spline's first derivative, continuous there).

    At control point k the derivative is (M - 1) (p_{k+1} - p_{k-1}) / 2, with the linear
    phantom points of :mod:`lanelab.geometry.catmull_rom` at the ends: (M - 1) (p_1 - p_0) and
    (M - 1) (p_{M-1} - p_{M-2}). Written as differences, not as its sampling matrix, which a step
    would make from host data."""
    xyz = points[..., :3]
    M = xyz.shape[-2]
    steps = xyz[..., 1:, :] - xyz[..., :-1, :]  # (..., M - 1, 3)
    padded = torch.cat([steps[..., :1, :], steps, steps[..., -1:, :]], dim=-2)  # each end's step twice
    tangent = (padded[..., 1:, :] + padded[..., :-1, :]).mul_((M - 1) / 2)
    return tangent / tangent.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(xyz.dtype).eps)


def normal_plane_offsets(points: Tensor, others: Tensor) -> Tensor:
    """Signed distances (B, N, M, N', M') of every point of ``others`` (B, N', M', >=3) from
    the normal plane of every point of ``points`` (B, N, M, >=3): t_im · (q_jn - p_im)."""
    xyz = points[..., :3]
    t = curve_tangents(xyz)
    along = torch.einsum("bimc,bjnc->bimjn", t, others[..., :3])
    return along.sub_((t * xyz).sum(-1)[..., None, None])


def parallel_neighbours(points: Tensor, num_neighbors: int = 2, tie_margin: float = 0.0) -> Tensor:
    """Indices (B, N, M, N, k) of the k = min(num_neighbors, M) points of every line j nearest
    to the normal plane of query (i, m), nearest first (j = i included; callers mask it);
    tie_margin: metres per position that settle near-ties for the earlier point (runtime.ranking)."""
    offsets = normal_plane_offsets(points, points).abs_()
    k = min(num_neighbors, points.shape[-2])
    return topk(offsets, k, margin=tie_margin)[1]


def temporal_neighbours(
    points: Tensor, memory_points: Tensor, memory_valid: Tensor, m_tca: int = 10
) -> tuple[Tensor, Tensor]:
    """The m_tca valid memory tokens nearest (3D euclidean) to every query point.

    points (B, N, M, >=3); memory_points (B, K, >=3), already propagated into the current
    frame; memory_valid (B, K) bool. Returns index (B, N, M, k_t) and valid (B, N, M, k_t)
    with k_t = min(m_tca, K), nearest first.
    """
    B, N, M = points.shape[:3]
    # Exact distances (not the matmul shortcut), so near-ties resolve the same on every device;
    # in float32 at least: bf16 has metres of spacing at 100 m. Differences written out rather
    # than torch.cdist, which ONNX cannot express.
    dtype = torch.promote_types(points.dtype, torch.float32)
    offsets = points[..., :3].reshape(B, N * M, 1, 3).to(dtype) - memory_points[:, None, :, :3].to(dtype)
    distance = offsets.square().sum(-1).sqrt()  # (B, N·M, K)
    distance = distance.masked_fill_(~memory_valid[:, None, :], torch.inf)
    k = min(m_tca, memory_points.shape[1])
    nearest, index = topk(distance, k)
    return index.view(B, N, M, k), nearest.isfinite().view(B, N, M, k)


def find_neighbours(
    points: Tensor,
    memory_points: Tensor | None = None,
    memory_valid: Tensor | None = None,
    line_mask: Tensor | None = None,
    num_neighbors: int = 2,
    m_tca: int = 10,
    use_sla: bool = True,
    use_pna: bool = True,
    use_tca: bool = True,
    pna_tie_margin: float = 0.0,
) -> Neighbours:
    """The active keys of every query of lines ``points`` (B, N, M, >=3) (metres).

    memory_points (B, K, >=3) / memory_valid (B, K): the propagated memory (None or K = 0: no
    TCA); line_mask (B, N) bool: False for padded lines (None: all lines real); pna_tie_margin:
    see :func:`parallel_neighbours`.
    """
    B, N, M = points.shape[:3]
    if line_mask is None:
        line_mask = torch.ones(B, N, dtype=torch.bool, device=points.device)
    neighbours = Neighbours(line_valid=line_mask, use_sla=use_sla)
    if use_pna:
        neighbours.pna_index = parallel_neighbours(points, num_neighbors, pna_tie_margin)
        other_line = ~torch.eye(N, dtype=torch.bool, device=points.device)  # (i, j): j != i
        valid = other_line[None] & line_mask[:, None, :]  # (B, N_i, N_j)
        neighbours.pna_valid = valid[:, :, None, :, None].expand_as(neighbours.pna_index)
    if use_tca and memory_points is not None and memory_points.shape[1] > 0:
        if memory_valid is None:
            memory_valid = torch.ones(memory_points.shape[:2], dtype=torch.bool, device=points.device)
        neighbours.tca_index, neighbours.tca_valid = temporal_neighbours(points, memory_points, memory_valid, m_tca)
    return neighbours


def _scatter_keys(index: Tensor, valid: Tensor, num_keys: int) -> Tensor:
    """Boolean (B, Q, num_keys), True at index (B, Q, k) where valid (invalid entries are sent
    to a spare column, cut off after)."""
    B, Q = index.shape[:2]
    mask = torch.zeros(B, Q, num_keys + 1, dtype=torch.bool, device=index.device)
    mask.scatter_(2, index.masked_fill(~valid, num_keys), True)
    return mask[..., :num_keys]


def neighbour_masks(neighbours: Neighbours, num_lines: int, num_points: int, num_memory: int) -> dict[str, Tensor]:
    """Boolean masks (B, N·M, N·M + K) over [current queries (line-major) ‖ memory tokens] of
    the relations in ``neighbours``: "sla", "pna", "tca" (those switched on)."""
    N, M, K = num_lines, num_points, num_memory
    B = neighbours.line_valid.shape[0]
    device = neighbours.line_valid.device
    masks: dict[str, Tensor] = {}
    if neighbours.use_sla:
        line = torch.arange(N, device=device).repeat_interleave(M)  # line of every current token
        same_line = line[:, None] == line[None, :]  # (NM, NM) block diagonal
        sla = same_line[None] & neighbours.line_valid[:, None, :].repeat_interleave(M, dim=2)
        masks["sla"] = torch.cat([sla, sla.new_zeros(B, N * M, K)], dim=2)
    if neighbours.pna_index is not None:
        # Key token of (line j, point n) is j·M + n.
        lines = torch.arange(N, device=device)[None, None, None, :, None]
        token = (lines * M + neighbours.pna_index).reshape(B, N * M, -1)
        masks["pna"] = _scatter_keys(token, neighbours.pna_valid.reshape(B, N * M, -1), N * M + K)
    if neighbours.tca_index is not None:
        token = (N * M + neighbours.tca_index).reshape(B, N * M, -1)
        masks["tca"] = _scatter_keys(token, neighbours.tca_valid.reshape(B, N * M, -1), N * M + K)
    return masks


def sta_masks(
    points: Tensor,
    memory_points: Tensor | None = None,
    memory_valid: Tensor | None = None,
    line_mask: Tensor | None = None,
    num_neighbors: int = 2,
    m_tca: int = 10,
) -> dict[str, Tensor]:
    """Boolean masks (B, N·M, N·M + K) of SLA, PNA and TCA for lines ``points`` (B, N, M, >=3)
    and the propagated memory (B, K, >=3) (see :func:`find_neighbours`). Row q = i·M + m is
    query (i, m); columns are the current queries in the same order, then the memory tokens."""
    neighbours = find_neighbours(points, memory_points, memory_valid, line_mask, num_neighbors, m_tca)
    num_memory = 0 if memory_points is None else memory_points.shape[1]
    return neighbour_masks(neighbours, points.shape[1], points.shape[2], num_memory)


def density(masks: dict[str, Tensor]) -> dict[str, float]:
    """Fraction of active relations of each mask and of their union ("all") — the ~10 % of
    supplementary C.2 for the paper's configuration."""
    union = torch.stack(list(masks.values())).any(0)
    fractions = {name: mask.float().mean().item() for name, mask in masks.items()}
    fractions["all"] = union.float().mean().item()
    return fractions
