"""Regularisers from lane priors: LaneCPP's spatial ones and SparseLaneSTP's temporal one.

Spatial (SparseLaneSTP §3.3 adopts LaneCPP's scheme; LaneCPP's exact formulas are not
reproduced here, these follow its three stated priors):
- parallelism: neighbouring lanes keep their distance. For every control point of a lane the
  corresponding point on its right neighbour is where the lane's normal plane cuts it
  (LaneCPP's orthogonal correspondence, the one PNA uses); the loss is the mean absolute
  deviation of that distance from its mean along the lane.
- surface smoothness: the road between neighbouring lanes is a smooth surface. Its normal,
  tangent × (correspondence - point), should turn slowly along the lane: mean L1 change of the
  unit normal between consecutive control points (zero on any plane, flat or tilted).
- curvature limit: the curvature κ = |f' × f''| / |f'|^3 of the Catmull-Rom curve, from its
  first and second derivatives, penalised where it exceeds max_curvature: mean of
  relu(κ / κ_max - 1).
Terms are weighted by the predicted visibility (detached, so that hiding a lane is no way
out) and apply to the lines the matcher assigned to a lane.

Temporal (eq. 12-13): the current prediction should stay near an exponential moving average
of the past predictions of the same lane, weighted by the averaged visibility:
    L_temp = 1/N Σ_i ∫ f̄_v,i(s) |f_3D,i(s) - f̄_3D,i(s)|_1 ds,   f̄^(t) = α f^(t) + (1 - α) f̄^(t-1).
The past predictions are the memory queue's lines, propagated into the current frame (eq. 10).
The paper leaves open which past line is "the same lane" and how curves of different frames
are compared (after ego motion equal curve arguments s are different places), so: every
current line is compared, point by point, with the orthogonal correspondence on the nearest
stored line of each past frame (mean L1 distance below max_distance, else that frame has no
counterpart), and the EMA runs over the T memory frames, oldest first. The EMA target is
detached (a teacher, as EMA targets are); the integral over s is the mean over control points.
"""

from __future__ import annotations

import torch
from torch import Tensor

from lanelab.geometry import sampling_matrix
from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.sta_masks import curve_tangents, normal_plane_offsets

_EPS = 1e-6


def orthogonal_correspondence(points: Tensor, others: Tensor) -> tuple[Tensor, Tensor]:
    """Where the normal plane of every control point of ``points`` (B, N, M, D) cuts every line
    of ``others`` (B, L, M', D): linear interpolation between the two consecutive points of the
    line on either side of the plane (all D channels). Where a line crosses the plane more than
    once, the crossing nearest to the plane's points wins.
    Returns points (B, N, M, L, D) and hit (B, N, M, L) bool (False: the plane misses the line)."""
    offset = normal_plane_offsets(points, others)  # (B, N, M, L, M')
    before, after = offset[..., :-1], offset[..., 1:]
    crossing = (before * after <= 0) & (before != after)  # the plane separates (or touches) the two points
    segment = (before.abs() + after.abs()).masked_fill(~crossing, torch.inf).argmin(-1, keepdim=True)
    hit = crossing.any(-1)
    a, b = before.gather(-1, segment), after.gather(-1, segment)
    t = a / torch.where(hit[..., None], a - b, torch.ones_like(a))  # in [0, 1] where hit
    B, N, M = points.shape[:3]
    lines = others[:, None, None].expand(B, N, M, *others.shape[1:])  # (B, N, M, L, M', D)
    index = segment[..., None].expand(*segment.shape, others.shape[-1])
    start = lines.gather(-2, index)[..., 0, :]
    end = lines.gather(-2, index + 1)[..., 0, :]
    return start + t * (end - start), hit


def right_neighbours(points: Tensor, lines: Tensor) -> tuple[Tensor, Tensor]:
    """Index (B, N) of the next line to the right (smallest positive mean x offset) among the
    lines (B, N) bool, and whether there is one (B, N)."""
    x = points[..., 0].detach()
    offset = (x[:, None, :, :] - x[:, :, None, :]).mean(-1)  # (B, i, j): mean x_j - x_i
    candidate = lines[:, :, None] & lines[:, None, :] & (offset > 0)
    distance, neighbour = offset.masked_fill(~candidate, torch.inf).min(-1)
    return neighbour, distance.isfinite()


def parallelism_and_surface(points: Tensor, lines: Tensor) -> tuple[Tensor, Tensor]:
    """Parallelism and surface-smoothness losses of control points (B, N, M, 4) of the lines
    (B, N) bool, each pair of right neighbours once; means over the pairs (0 without any)."""
    B, N, M, D = points.shape
    neighbour, has_neighbour = right_neighbours(points, lines)
    correspondence, hit = orthogonal_correspondence(points, points)
    pick = neighbour[:, :, None, None]
    partner = correspondence.gather(3, pick[..., None].expand(B, N, M, 1, D))[:, :, :, 0]  # (B, N, M, 4)
    hit = hit.gather(3, pick.expand(B, N, M, 1))[..., 0] & has_neighbour[..., None]
    weight = (hit * points[..., 3].clamp(0, 1) * partner[..., 3].clamp(0, 1)).detach()  # (B, N, M)

    across = partner[..., :3] - points[..., :3]
    width = across.norm(dim=-1)
    mean_width = (weight * width).sum(-1, keepdim=True) / weight.sum(-1, keepdim=True).clamp_min(_EPS)
    parallel = (weight * (width - mean_width).abs()).sum(-1) / weight.sum(-1).clamp_min(_EPS)

    normal = torch.linalg.cross(curve_tangents(points), across)
    normal = normal / normal.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    turn = (normal[:, :, 1:] - normal[:, :, :-1]).abs().sum(-1)  # (B, N, M - 1)
    both = weight[..., 1:] * weight[..., :-1]
    surface = (both * turn).sum(-1) / both.sum(-1).clamp_min(_EPS)

    pairs = weight.sum(-1) > 0
    if not bool(pairs.any()):
        return points.new_zeros(()), points.new_zeros(())
    return parallel[pairs].mean(), surface[pairs].mean()


def curvature_excess(points: Tensor, lines: Tensor, max_curvature: float) -> Tensor:
    """Mean relu(κ / κ_max - 1) over the control points and the midpoints between them of the
    lines (B, N) bool of Catmull-Rom control points (B, N, M, 4), weighted by visibility."""
    M = points.shape[-2]
    s = torch.linspace(0.0, 1.0, 2 * M - 1, dtype=points.dtype, device=points.device)
    xyz = points[..., :3]
    first, second = sampling_matrix(M, s, 1) @ xyz, sampling_matrix(M, s, 2) @ xyz
    curvature = torch.linalg.cross(first, second).norm(dim=-1) / first.norm(dim=-1).clamp_min(_EPS) ** 3
    excess = torch.relu(curvature / max_curvature - 1)
    weight = ((sampling_matrix(M, s) @ points[..., 3:]).squeeze(-1).clamp(0, 1) * lines[..., None]).detach()
    return (weight * excess).sum() / weight.sum().clamp_min(_EPS)


def temporal_consistency(current: Tensor, memory: MemoryState | None, alpha: float, max_distance: float) -> Tensor:
    """Eq. 12-13 for control points current (B, N, M, 4) and the propagated memory (lines of M
    points, frame slots newest first, as MemoryQueue.read returns them). 0 without memory."""
    B, N, M, _ = current.shape
    if memory is None or memory.points.shape[1] == 0:
        return current.new_zeros(())
    frames = int(memory.age.max())
    per_frame = memory.points.shape[1] // (M * frames)
    with torch.no_grad():
        past = memory.points.view(B, frames * per_frame, M, 4).to(current.dtype)
        correspondence, hit = orthogonal_correspondence(current, past)  # (B, N, M, L, 4), (B, N, M, L)
        hit &= memory.valid.view(B, 1, 1, frames * per_frame, M)[..., 0]
        distance = (correspondence[..., :3] - current[..., None, :3]).abs().sum(-1)
        count = hit.sum(2)  # (B, N, L)
        line_distance = ((distance * hit).sum(2) / count.clamp_min(1)).masked_fill(count == 0, torch.inf)
        best_distance, best = line_distance.view(B, N, frames, per_frame).min(-1)  # per past frame
        pick = best[:, :, None, :, None].expand(B, N, M, frames, 1)
        correspondence = correspondence.view(B, N, M, frames, per_frame, 4)
        correspondence = correspondence.gather(4, pick[..., None].expand(-1, -1, -1, -1, -1, 4))[..., 0, :]
        linked = hit.view(B, N, M, frames, per_frame).gather(4, pick)[..., 0]
        linked &= (best_distance < max_distance)[:, :, None]  # (B, N, M, frames)

        ema, seen = torch.zeros_like(current), torch.zeros_like(current[..., 0], dtype=torch.bool)
        for k in reversed(range(frames)):  # slot k holds frame t - (k + 1): oldest first
            past = correspondence[..., k, :]
            step = torch.where(seen[..., None], alpha * past + (1 - alpha) * ema, past)
            ema = torch.where(linked[..., k, None], step, ema)
            seen |= linked[..., k]
        target = alpha * current + (1 - alpha) * ema  # f̄^(t), eq. 13
        weight = target[..., 3].clamp(0, 1) * seen
    return (weight * (current[..., :3] - target[..., :3]).abs().sum(-1)).sum() / (B * N * M)
