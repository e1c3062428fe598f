"""Lanes as M control points (x, y, z, visibility) at fixed, uniform y: how they become dense lanes.

Two representations of the same M points (SparseLaneSTP's ablation, Table 1):
- ``"catmull_rom"``: control points of a Catmull-Rom spline (:mod:`lanelab.geometry.catmull_rom`);
- ``"discrete"``: LATR's points at fixed y, linearly interpolated in between.
Visibility is always interpolated linearly: a spline through probabilities overshoots [0, 1],
and a clamped overshoot has no gradient, so a lane's end could never be learnt there.

Sampling is a matrix product with a pair of bases (geometry, visibility), each (..., S, M):
:class:`LaneCurves` builds them for longitudinal positions y in metres, :func:`sample_lanes`
applies them. The head that predicts control points and the loss that trains them share it.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from lanelab.geometry.catmull_rom import curve_arguments, sampling_matrix
from lanelab.geometry.checks import holds

REPRESENTATIONS = ("catmull_rom", "discrete")

# Curve arguments this far outside [0, 1] are rounding noise; further is an error.
_S_TOLERANCE = 1e-6


def lane_bases(representation: str, num_points: int, s: Tensor) -> tuple[Tensor, Tensor]:
    """Matrices (..., S, M) that sample M control points at curve arguments s (..., S) in
    [0, 1]: one for the geometry, following the representation, one for visibility, linear."""
    u = s.clamp(0, 1) * (num_points - 1)
    linear = (1 - (u[..., None] - torch.arange(num_points, dtype=s.dtype, device=s.device)).abs()).clamp(min=0)
    if representation == "catmull_rom":
        return sampling_matrix(num_points, s), linear
    return linear, linear


def sample_lanes(points: Tensor, bases: tuple[Tensor, Tensor]) -> Tensor:
    """Control points (..., M, 4) sampled with ``lane_bases`` (S, M), or (B, S, M) for points
    (B, N, M, 4) -> (..., S, 4): x, y, z from the geometry basis, v from the visibility one."""
    geometry, visibility = (basis[:, None] if basis.dim() == 3 else basis for basis in bases)
    return torch.cat([geometry @ points[..., :3], visibility @ points[..., 3:]], dim=-1)


@dataclass(frozen=True)
class LaneCurves:
    """The lanes of one representation with num_points control points M spread uniformly over
    y_range (y_start, y_end), metres."""

    representation: str
    num_points: int
    y_range: tuple[float, float]

    def __post_init__(self) -> None:
        if self.representation not in REPRESENTATIONS:
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, got {self.representation!r}")
        object.__setattr__(self, "y_range", tuple(self.y_range))

    def bases(self, y: Tensor) -> tuple[Tensor, Tensor]:
        """The bases (..., S, M) of geometry and visibility at longitudinal positions y (..., S),
        which must lie in y_range."""
        s = curve_arguments(y, *self.y_range)
        if not holds((s >= -_S_TOLERANCE) & (s <= 1 + _S_TOLERANCE)):
            raise ValueError(f"the positions y must lie in the control points' y range {self.y_range}")
        return lane_bases(self.representation, self.num_points, s)

    def sample(self, points: Tensor, y: Tensor) -> Tensor:
        """Control points (..., M, 4) at positions y (S,), or (B, N, M, 4) at (B, S) -> (..., S, 4)."""
        return sample_lanes(points, self.bases(y))


def interpolate_in_y(y: Tensor, grid_y: Tensor, values: Tensor) -> tuple[Tensor, Tensor]:
    """Values (..., S) given at ascending positions grid_y (..., S), linearly interpolated at
    positions y (..., Q) -> (..., Q), and whether each y lies inside the grid (..., Q) bool;
    outside it the value is the nearest end's (clamped)."""
    hi = torch.searchsorted(grid_y.contiguous(), y.contiguous()).clamp(1, grid_y.shape[-1] - 1)
    lo = hi - 1
    y0, y1 = grid_y.gather(-1, lo), grid_y.gather(-1, hi)
    t = ((y - y0) / (y1 - y0)).clamp(0, 1)
    interpolated = values.gather(-1, lo) * (1 - t) + values.gather(-1, hi) * t
    inside = (y >= grid_y[..., :1]) & (y <= grid_y[..., -1:])
    return interpolated, inside
