"""The road surface from the ego trajectory (SparseLaneSTP, supplementary E, "3D surface model").

The ego pose stands on the road (``base_link`` is on the ground under the rear axle), so each
pose spans the road around it: its position ``p`` and its lateral axis ``l`` (lane-frame x,
to the right) give the road's cross-section line ``p + d l`` there. Between consecutive
poses the surface is the linear blend of their two cross-sections,

    X(s, d) = (1 - u) (p_i + d l_i) + u (p_{i+1} + d l_{i+1}),   u = (s - s_i) / (s_{i+1} - s_i),

a first-degree spline surface in the trajectory's arc length ``s`` and the lateral offset
``d`` (positive to the right). A segment is a plane segment whenever the two poses share
their lateral axis (a straight road, tilted as the poses are); on curves it is the ruled
surface between two plane cross-sections. Beyond the first and last pose the surface goes on
as the plane of that pose. A ray meets a segment where a quadratic in ``u`` vanishes
(:meth:`RoadSurface.intersect`): analytic, with no iteration.

Poses closer than ``min_spacing_m`` to the previous kept one are skipped (an ego that stands
still adds no surface), so segments never degenerate.
"""

from __future__ import annotations

import numpy as np

EXTEND_M = 1000.0  # the planes of the first and last pose reach this far beyond them
_U_TOLERANCE = 1e-9  # a hit on the shared edge of two segments belongs to both


class RoadSurface:
    """The first-degree spline surface through the poses T_world_lane (N, 4, 4), in time order.

    ``s`` (K,) is the arc length of the kept poses (keys) along the trajectory's chords,
    ``frame_s`` (N,) that of every pose given (a skipped pose: its distance past the last key).
    """

    def __init__(self, T_world_lane: np.ndarray, min_spacing_m: float = 0.2) -> None:
        positions = T_world_lane[:, :3, 3]
        steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
        keep = [0]
        for i in range(1, len(positions)):
            if np.linalg.norm(positions[i] - positions[keep[-1]]) >= min_spacing_m:
                keep.append(i)
        self.frame_s = np.concatenate([[0.0], np.cumsum(steps)])
        self.keys = np.array(keep)
        p, lateral, forward = positions[keep], T_world_lane[keep, :3, 0], T_world_lane[keep, :3, 1]
        self.s = self.frame_s[keep]
        # A virtual key before the first and after the last pose: their planes extend the surface.
        self._p = np.concatenate([p[:1] - EXTEND_M * forward[:1], p, p[-1:] + EXTEND_M * forward[-1:]])
        self._l = np.concatenate([lateral[:1], lateral, lateral[-1:]])
        self._s = np.concatenate([self.s[:1] - EXTEND_M, self.s, self.s[-1:] + EXTEND_M])

    @property
    def num_segments(self) -> int:
        """Segments, the two extensions included: segment j spans virtual keys j and j + 1."""
        return len(self._s) - 1

    def segments_between(self, s_from: float, s_to: float) -> np.ndarray:
        """Indices of the segments that cover any of [s_from, s_to]."""
        first = max(int(np.searchsorted(self._s, s_from, side="right")) - 1, 0)
        last = min(int(np.searchsorted(self._s, s_to, side="left")), self.num_segments)
        return np.arange(first, max(last, first + 1))

    def cross_sections(self, s_from: float, s_to: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cross-sections that bound the segments covering [s_from, s_to]: arc lengths s (C,),
        points p (C, 3) and lateral axes l (C, 3) in the world frame (the surface there is p + d l)."""
        segments = self.segments_between(s_from, s_to)
        at = np.append(segments, segments[-1] + 1)
        return self._s[at], self._p[at], self._l[at]

    def point(self, s: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Surface points (M, 3) in the world frame at arc lengths s (M,) and lateral offsets d (M,)."""
        j = np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, self.num_segments - 1)
        u = ((s - self._s[j]) / (self._s[j + 1] - self._s[j]))[:, None]
        d = np.asarray(d, float)[:, None]
        return (1 - u) * (self._p[j] + d * self._l[j]) + u * (self._p[j + 1] + d * self._l[j + 1])

    def intersect(self, origin: np.ndarray, directions: np.ndarray,
                  segments: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Where rays from ``origin`` (3,) along ``directions`` (N, 3) first meet the surface.

        segments: the segments to try (default all). Returns points (N, 3) in the world frame,
        their surface coordinates s (N,) and d (N,), and valid (N,) bool: False (and NaN) where
        a ray meets none of the segments ahead of the origin.
        """
        j = np.arange(self.num_segments) if segments is None else np.asarray(segments)
        A, C = self._p[j], self._l[j]  # (S, 3)
        B, D = self._p[j + 1] - A, self._l[j + 1] - C
        e1, e2 = _normal_pair(directions)  # (N, 3) each, both orthogonal to the ray
        # X(u, d) - origin = t * ray; dotted with e1 and e2 the ray term vanishes:
        # a_k + u b_k + d c_k + u d g_k = 0 for k = 1, 2, which gives a quadratic in u.
        a1, a2 = (e @ (A - origin).T for e in (e1, e2))  # (N, S)
        b1, b2 = e1 @ B.T, e2 @ B.T
        c1, c2 = e1 @ C.T, e2 @ C.T
        g1, g2 = e1 @ D.T, e2 @ D.T
        qa = b1 * g2 - b2 * g1
        qb = a1 * g2 + b1 * c2 - a2 * g1 - b2 * c1
        qc = a1 * c2 - a2 * c1
        roots = _quadratic_roots(qa, qb, qc)  # (2, N, S)
        best_t = np.full(len(directions), np.inf)
        best = np.full((len(directions), 3), np.nan)
        best_s, best_d = np.full(len(directions), np.nan), np.full(len(directions), np.nan)
        for u in roots:
            # d from whichever equation is better conditioned
            den1, den2 = c1 + u * g1, c2 + u * g2
            use1 = np.abs(den1) >= np.abs(den2)
            with np.errstate(invalid="ignore", divide="ignore"):
                d = np.where(use1, -(a1 + u * b1) / den1, -(a2 + u * b2) / den2)
            X = A + u[..., None] * B + d[..., None] * C + (u * d)[..., None] * D  # (N, S, 3)
            t = np.einsum("nsk,nk->ns", X - origin, directions) / np.einsum("nk,nk->n", directions, directions)[:, None]
            ok = np.isfinite(u) & np.isfinite(d) & (u >= -_U_TOLERANCE) & (u <= 1 + _U_TOLERANCE) & (t > 0)
            t = np.where(ok, t, np.inf)
            k = np.argmin(t, axis=1)
            rows = np.arange(len(directions))
            better = t[rows, k] < best_t
            best_t = np.where(better, t[rows, k], best_t)
            best[better] = X[rows, k][better]
            s = self._s[j][k] + u[rows, k] * (self._s[j + 1] - self._s[j])[k]
            best_s, best_d = np.where(better, s, best_s), np.where(better, d[rows, k], best_d)
        return best, best_s, best_d, np.isfinite(best_t)


def _normal_pair(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) orthogonal to each direction (N, 3) and to each other."""
    unit = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    # Cross with the axis least aligned with the ray, so the product never vanishes.
    axis = np.eye(3)[np.argmin(np.abs(unit), axis=1)]
    e1 = np.cross(unit, axis)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(unit, e1)


def _quadratic_roots(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Both real roots (2, ...) of a u^2 + b u + c = 0, elementwise, NaN where there is none.

    Written as q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2, roots q / a and c / q: stable when a is
    tiny (a plane segment, a = 0 exactly, leaves the one root -c / b).
    """
    disc = b * b - 4 * a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        q = -0.5 * (b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(np.where(disc >= 0, disc, np.nan)))
        first = np.where(a != 0, q / np.where(a != 0, a, 1.0), np.nan)
        second = np.where(q != 0, c / np.where(q != 0, q, 1.0), np.nan)
    return np.stack([first, second])
