"""The road: a reference line in the world frame, parameterised by arc length, and its surface.

World frame = ``odom`` (x east, y north, z up). s is the horizontal arc length along the
reference line, d the lateral offset from it, positive to the right. The road is three
profiles of s: curvature (1/m, positive turns left) integrates to the heading and the
plan view, grade (dz/ds) to the elevation, and bank (rad, positive = right side lower)
tilts the cross-section. They are sampled on a fine uniform grid of s; between grid
points everything is linear.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

from data_ingest.synth.cross_section import CrossSection

GRID_STEP_M = 0.25
MAX_BANK_RAD = 0.05  # superelevation of the tightest curves (5 %)
BANK_FULL_RADIUS_M = 250.0  # curves this tight or tighter get the full bank
MAX_TURN_RAD = np.deg2rad(110.0)  # of a single curve

Profile = Union[float, Callable[[np.ndarray], np.ndarray]]
_X, _Y, _Z, _HEADING, _BANK, _CURVATURE, _GRADE = range(7)


class Road:
    """A road of length ``len(curvature) * step`` metres with its cross-section.

    curvature, grade, bank: (S,) profiles on the grid s = 0, step, 2 step, ...
    """

    def __init__(self, curvature: np.ndarray, grade: np.ndarray, bank: np.ndarray,
                 cross_section: CrossSection, step: float = GRID_STEP_M) -> None:
        self.step = step
        self.cross_section = cross_section
        heading = _integrate(curvature, step)
        x, y = _integrate(np.cos(heading), step), _integrate(np.sin(heading), step)
        self._table = np.stack([x, y, _integrate(grade, step), heading, bank, curvature, grade], axis=-1)
        self._travel_tables: dict[float, np.ndarray] = {}

    @classmethod
    def from_profiles(cls, length: float, cross_section: CrossSection, curvature: Profile = 0.0,
                      grade: Profile = 0.0, bank: Profile | None = None) -> Road:
        """A road from explicit profiles: constants or vectorised functions of s (N,) -> (N,).

        Without ``bank``, the road banks into its curves (:func:`superelevation`).
        """
        s = np.arange(int(np.ceil(length / GRID_STEP_M)) + 1) * GRID_STEP_M
        curvature_s = _evaluate(curvature, s)
        bank_s = superelevation(curvature_s) if bank is None else _evaluate(bank, s)
        return cls(curvature_s, _evaluate(grade, s), bank_s, cross_section)

    @property
    def length(self) -> float:
        return (len(self._table) - 1) * self.step

    def _sample(self, s: np.ndarray, columns: list[int]) -> np.ndarray:
        """(..., C) linear interpolation of table columns at s (...), clamped to the road's ends."""
        u = np.clip(np.asarray(s, float) / self.step, 0.0, len(self._table) - 1.000001)
        i = u.astype(np.int64)
        w = (u - i)[..., None]
        table = self._table[:, columns]
        return table[i] * (1 - w) + table[i + 1] * w

    def heading(self, s: np.ndarray) -> np.ndarray:
        return self._sample(s, [_HEADING])[..., 0]

    def curvature(self, s: np.ndarray) -> np.ndarray:
        return self._sample(s, [_CURVATURE])[..., 0]

    def grade(self, s: np.ndarray) -> np.ndarray:
        return self._sample(s, [_GRADE])[..., 0]

    def bank(self, s: np.ndarray) -> np.ndarray:
        return self._sample(s, [_BANK])[..., 0]

    def surface(self, s: np.ndarray, d: np.ndarray, height: float | np.ndarray = 0.0) -> np.ndarray:
        """World points (..., 3) at arc length s, lateral offset d and ``height`` above the surface.

        s, d, height broadcast together. Heights are along world z (objects stand upright).
        """
        s, d = np.broadcast_arrays(np.asarray(s, float), np.asarray(d, float))
        x, y, z, heading, bank = np.moveaxis(self._sample(s, [_X, _Y, _Z, _HEADING, _BANK]), -1, 0)
        across = d * np.cos(bank)
        return np.stack([x + across * np.sin(heading), y - across * np.cos(heading),
                         z - d * np.sin(bank) + height], axis=-1)

    def travelled(self, s: np.ndarray, d: float) -> np.ndarray:
        """(...) distance driven along the line at constant offset d from s = 0 to s (...).

        A line right of the reference is longer on left curves: d(distance)/ds = 1 + curvature * d.
        """
        return np.interp(s, self._grid_s(), self._travel_table(d))

    def s_after(self, distance: np.ndarray, d: float) -> np.ndarray:
        """(...) arc length reached after driving ``distance`` (...) along offset d (inverse of :meth:`travelled`)."""
        return np.interp(distance, self._travel_table(d), self._grid_s())

    def _grid_s(self) -> np.ndarray:
        return np.arange(len(self._table)) * self.step

    def _travel_table(self, d: float) -> np.ndarray:
        if d not in self._travel_tables:
            self._travel_tables[d] = _integrate(1.0 + self._table[:, _CURVATURE] * d, self.step)
        return self._travel_tables[d]

    def height(self, s: np.ndarray, d: np.ndarray) -> np.ndarray:
        """(...) world z of the surface at (s, d); cheaper than :meth:`surface` when only z matters."""
        z, bank = np.moveaxis(self._sample(np.broadcast_arrays(s, d)[0], [_Z, _BANK]), -1, 0)
        return z - np.asarray(d) * np.sin(bank)


def superelevation(curvature: np.ndarray) -> np.ndarray:
    """(N,) bank (rad) of a road with curvature (N,): tilted into its curves, at most 5 %."""
    return -MAX_BANK_RAD * np.clip(curvature * BANK_FULL_RADIUS_M, -1.0, 1.0)


def _evaluate(profile: Profile, s: np.ndarray) -> np.ndarray:
    return np.broadcast_to(profile(s) if callable(profile) else np.asarray(profile, float), s.shape).astype(float)


def _integrate(values: np.ndarray, step: float) -> np.ndarray:
    """Cumulative trapezoidal integral of (S,) samples, starting at 0."""
    return np.concatenate([[0.0], np.cumsum((values[1:] + values[:-1]) * (step / 2))])


# --- procedural profiles -------------------------------------------------------------------


@dataclass(frozen=True)
class RoadStyle:
    """How roads of an environment bend and climb (ranges are drawn uniformly)."""

    radius_m: tuple[float, float]  # drawn log-uniformly; the lower end is raised to min_curve_radius
    straight_m: tuple[float, float]
    transition_m: tuple[float, float]  # clothoid-like: curvature ramps linearly
    arc_m: tuple[float, float]
    max_grade: float
    grade_length_m: tuple[float, float]  # of a constant-grade stretch
    vertical_radius_m: tuple[float, float]  # of crests and sags: length = |grade change| * radius
    hilly_probability: float


ROAD_STYLES = {
    "highway": RoadStyle((300.0, 2500.0), (100.0, 500.0), (60.0, 150.0), (100.0, 400.0), 0.04,
                         (100.0, 300.0), (2000.0, 6000.0), 0.6),
    "rural": RoadStyle((100.0, 800.0), (30.0, 300.0), (20.0, 60.0), (40.0, 200.0), 0.07,
                       (40.0, 200.0), (500.0, 2000.0), 0.75),
    "urban": RoadStyle((100.0, 600.0), (50.0, 300.0), (10.0, 40.0), (30.0, 150.0), 0.05,
                       (60.0, 200.0), (800.0, 3000.0), 0.5),
}
CREST_OR_SAG_PROBABILITY = 0.7  # that the next grade has the other sign


def random_curvature(rng: np.random.Generator, length: float, style: RoadStyle, min_radius: float,
                     max_straight: float | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """Straights, clothoid transitions and arcs of both hands, as curvature(s); straights no
    longer than max_straight metres (None: the style's lengths)."""
    low = max(style.radius_m[0], min_radius)
    high = max(style.radius_m[1], low)
    straight = style.straight_m if max_straight is None else tuple(min(x, max_straight) for x in style.straight_m)
    s = rng.uniform(0.0, straight[1])  # the drive may start on a curve
    knots = [(0.0, 0.0), (s, 0.0)]
    while s < length:
        radius = float(np.exp(rng.uniform(np.log(low), np.log(high))))
        kappa = rng.choice([-1.0, 1.0]) / radius
        ramp_in, ramp_out = rng.uniform(*style.transition_m, size=2)
        arc = min(rng.uniform(*style.arc_m), radius * MAX_TURN_RAD)
        s += ramp_in
        knots.append((s, kappa))
        s += arc
        knots.append((s, kappa))
        s += ramp_out
        knots.append((s, 0.0))
        s += rng.uniform(*straight)
        knots.append((s, 0.0))
    return _piecewise_linear(knots)


def random_grade(rng: np.random.Generator, length: float, style: RoadStyle) -> Callable[[np.ndarray], np.ndarray]:
    """Constant grades joined by parabolic vertical curves (crests and sags), as grade(s)."""
    max_grade = style.max_grade if rng.random() < style.hilly_probability else 0.005
    grade = rng.uniform(-max_grade, max_grade)
    s, knots = 0.0, [(0.0, grade)]
    while s < length:
        s += rng.uniform(*style.grade_length_m)
        knots.append((s, grade))
        flip = -1.0 if rng.random() < CREST_OR_SAG_PROBABILITY else 1.0
        new_grade = flip * (np.sign(grade) or 1.0) * rng.uniform(0.3, 1.0) * max_grade
        s += abs(new_grade - grade) * rng.uniform(*style.vertical_radius_m)
        knots.append((s, new_grade))
        grade = new_grade
    return _piecewise_linear(knots)


def _piecewise_linear(knots: list[tuple[float, float]]) -> Callable[[np.ndarray], np.ndarray]:
    xs, ys = np.array(knots).T
    return lambda s: np.interp(s, xs, ys)


def random_road(rng: np.random.Generator, length: float, cross_section: CrossSection, min_radius: float,
                max_straight: float | None = None) -> Road:
    """A procedural road in the style of ``cross_section.environment``; straights of at most
    max_straight metres (None: the style's)."""
    style = ROAD_STYLES[cross_section.environment]
    return Road.from_profiles(length, cross_section, random_curvature(rng, length, style, min_radius, max_straight),
                              random_grade(rng, length, style))
