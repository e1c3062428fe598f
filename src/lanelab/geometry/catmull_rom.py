"""Catmull-Rom (CR) spline lanes, SparseLaneSTP supplementary A (eq. 14-21).

A lane is M control points P (M, D) (e.g. D = 4: x, y, z, visibility) at uniform curve
arguments s_k = k / (M - 1). Segment k spans [s_k, s_{k+1}] and blends p_{k-1}, p_k, p_{k+1},
p_{k+2} with the local basis [s~^3 s~^2 s~ 1] @ M~_CR, s~ = (s - s_k) / (s_{k+1} - s_k).
The curve passes through every control point.

For a fixed set of arguments s the blending is one (S, M) matrix A, the "s · M_CR(s)" of eq. 17,
so sampling a batch of curves is a single matmul: ``A @ P``.

Lanes are functions of the longitudinal coordinate y: control points sit at fixed, uniformly
spaced y in [y_start, y_end] and a sample at y has the argument s = (y - y_start) / (y_end - y_start)
(eq. 21).
"""

from __future__ import annotations

import torch
from torch import Tensor

from lanelab.geometry.checks import holds

# Eq. 15: local coefficient matrix M~_CR, rows for s~^3, s~^2, s~, 1; columns for p_{k-1}..p_{k+2}.
CR_MATRIX = 0.5 * torch.tensor(
    [
        [-1.0, 3.0, -3.0, 1.0],
        [2.0, -5.0, 4.0, -1.0],
        [-1.0, 0.0, 1.0, 0.0],
        [0.0, 2.0, 0.0, 0.0],
    ],
    dtype=torch.float64,
)

# Curve arguments this far outside [0, 1] are rounding noise and get clamped; further is an error.
_S_TOLERANCE = 1e-6


def cr_matrix(dtype: torch.dtype = torch.float64, device: torch.device | str | None = None) -> Tensor:
    """The 4 x 4 local CR coefficient matrix of eq. 15 in the given dtype and device."""
    return CR_MATRIX.to(dtype=dtype, device=device)


def _check_num_control_points(num_control_points: int) -> None:
    if num_control_points < 2:
        raise ValueError(f"a Catmull-Rom curve needs at least 2 control points, got {num_control_points}")


def _phantom_extension(num_control_points: int, dtype: torch.dtype, device: torch.device) -> Tensor:
    """(M + 2, M) matrix E with E @ P = [p_{-1}, p_0, ..., p_{M-1}, p_M].

    The paper leaves the outer neighbours of the end segments open. We extrapolate linearly,
    p_{-1} = 2 p_0 - p_1 and p_M = 2 p_{M-1} - p_{M-2}, so a straight row of control points
    gives an exactly straight curve, end segments included. Folding E into the sampling matrix
    keeps the phantom points invisible to callers.
    """
    m = num_control_points
    E = torch.zeros(m + 2, m, dtype=dtype, device=device)
    E[1:-1] = torch.eye(m, dtype=dtype, device=device)
    E[0, 0], E[0, 1] = 2.0, -1.0
    E[-1, -1], E[-1, -2] = 2.0, -1.0
    return E


def sampling_matrix(num_control_points: int, s: Tensor, derivative: int = 0) -> Tensor:
    """Basis matrix A (S, M) with curve(s) = A @ P for control points P (..., M, D).

    s: curve arguments (S,) in [0, 1] (any leading dims (..., S) work too, giving (..., S, M)).
    derivative: 0 for positions, 1 or 2 for the first or second derivative with respect to s
    (not s~: the chain rule multiplies by (M - 1) per order). s = 1 belongs to the last segment;
    a knot belongs to the segment it starts, which matters only for the second derivative
    (CR splines are C1, not C2). dtype and device follow s.
    """
    _check_num_control_points(num_control_points)
    if derivative not in (0, 1, 2):
        raise ValueError(f"derivative must be 0, 1 or 2, got {derivative}")
    if not holds((s >= -_S_TOLERANCE) & (s <= 1 + _S_TOLERANCE)):
        raise ValueError("curve arguments s must lie in [0, 1]")
    s = s.clamp(0.0, 1.0)
    # Under autocast the matmul below would come out in bf16/fp16 and no longer match the
    # dtype of s; the basis is cheap and wants full precision anyway.
    with torch.autocast(s.device.type, enabled=False):
        return _sampling_matrix(num_control_points, s, derivative)


def _sampling_matrix(num_control_points: int, s: Tensor, derivative: int) -> Tensor:
    num_segments = num_control_points - 1
    u = s * num_segments
    segment = u.floor().clamp(max=num_segments - 1)
    t = u - segment  # local argument s~ in [0, 1]
    one, zero = torch.ones_like(t), torch.zeros_like(t)
    if derivative == 0:
        powers = [t**3, t**2, t, one]
    elif derivative == 1:
        powers = [3 * t**2, 2 * t, one, zero]
    else:
        powers = [6 * t, 2 * one, zero, zero]
    scale = num_segments**derivative  # d s~ / d s = M - 1
    weights = scale * torch.stack(powers, dim=-1) @ cr_matrix(s.dtype, s.device)  # (..., S, 4)

    # Segment k blends p_{k-1}..p_{k+2}: columns k..k+3 of the phantom-extended points.
    columns = segment.long().unsqueeze(-1) + torch.arange(4, device=s.device)
    extended = torch.zeros(*s.shape, num_control_points + 2, dtype=s.dtype, device=s.device)
    extended = extended.scatter(-1, columns, weights)
    return extended @ _phantom_extension(num_control_points, s.dtype, s.device)


def evaluate(control_points: Tensor, s: Tensor, derivative: int = 0) -> Tensor:
    """Sample curves with control points (..., M, D) at arguments s (S,) -> (..., S, D)."""
    A = sampling_matrix(control_points.shape[-2], s.to(control_points), derivative)
    return A @ control_points


def curve_arguments(y: Tensor, y_start: float, y_end: float) -> Tensor:
    """Curve arguments s = (y - y_start) / (y_end - y_start) of longitudinal positions y (eq. 21)."""
    return (y - y_start) / (y_end - y_start)


def control_point_y(
    num_control_points: int,
    y_start: float,
    y_end: float,
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> Tensor:
    """The fixed longitudinal positions (M,) of the control points, uniform in [y_start, y_end]."""
    _check_num_control_points(num_control_points)
    return torch.linspace(y_start, y_end, num_control_points, dtype=dtype, device=device)


def _second_difference_gram(num_control_points: int, dtype: torch.dtype, device: torch.device) -> Tensor:
    """(M, M) matrix D^T D of the second differences p_{k-1} - 2 p_k + p_{k+1} (zero for M = 2)."""
    eye = torch.eye(num_control_points, dtype=dtype, device=device)
    D = eye[:-2] - 2 * eye[1:-1] + eye[2:]
    return D.T @ D


def fit_control_points(
    y: Tensor,
    values: Tensor,
    num_control_points: int,
    y_start: float,
    y_end: float,
    weights: Tensor | None = None,
    smoothness: float = 1e-3,
) -> Tensor:
    """Weighted least-squares control points (..., M, D) of dense lane samples.

    y: (..., P) longitudinal positions of the samples; each lane of the batch has its own.
    values: (..., P, D) what the curve should pass through (x, z, visibility, any features).
    weights: (..., P) non-negative sample weights, default 1. Samples with weight 0, with y
    outside [y_start, y_end], or with a NaN value are ignored, so padded lanes are fine.

    The fit minimises  sum_p w_p |A_p P - v_p|^2 + smoothness * sum_k |p_{k-1} - 2 p_k + p_{k+1}|^2.
    The second-difference penalty is what gives control points that no sample touches (beyond
    the observed part of a lane) a value: they continue the lane in a straight line instead of
    making the system singular, and it keeps weakly observed control points (whose basis barely
    reaches the samples) from amplifying label noise. The price is a small bias towards straight
    lanes: for a 100 m lane with 200 samples and control-point second differences of 0.1 m, about
    2e-5 m with the default, up to ~1 mm at the ends of a partly observed lane. smoothness=0
    recovers exactly representable curves exactly, but only lanes covering the whole range are
    then solvable. A lane with fewer than two distinct valid y comes back as NaN.
    The result has y's dtype.
    """
    _check_num_control_points(num_control_points)
    if smoothness < 0:
        raise ValueError(f"smoothness must be >= 0, got {smoothness}")
    s = curve_arguments(y, y_start, y_end)
    w = torch.ones_like(s) if weights is None else weights.to(s)
    valid = (w > 0) & (s >= 0) & (s <= 1) & values.isfinite().all(-1)
    s = torch.where(valid, s, torch.zeros_like(s))
    w = torch.where(valid, w, torch.zeros_like(w))
    values = torch.where(valid.unsqueeze(-1), values, torch.zeros_like(values))

    A = sampling_matrix(num_control_points, s)  # (..., P, M), one row per sample
    weighted_A = A * w.unsqueeze(-1)
    gram = weighted_A.transpose(-1, -2) @ A
    gram = gram + smoothness * _second_difference_gram(num_control_points, s.dtype, s.device)
    rhs = weighted_A.transpose(-1, -2) @ values.to(s)

    # Lanes without two distinct arguments get an identity system (so the batched solve never
    # fails on padding) and NaN results.
    observed_min = torch.where(valid, s, torch.full_like(s, torch.inf)).amin(-1)
    observed_max = torch.where(valid, s, torch.full_like(s, -torch.inf)).amax(-1)
    fittable = (observed_max > observed_min)[..., None, None]
    eye = torch.eye(num_control_points, dtype=s.dtype, device=s.device)
    control_points = torch.linalg.solve(torch.where(fittable, gram, eye), rhs)
    return torch.where(fittable, control_points, torch.full_like(control_points, float("nan")))
