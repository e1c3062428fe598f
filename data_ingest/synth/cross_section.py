"""The road's cross-section: lanes, painted lines, curbsides, merges/splits and the verges.

Everything is laid out by the lateral offset d from the road's reference line, positive to
the right (see :mod:`road`). The reference line is the centre line of a two-way road, or
the left edge line of a highway's carriageway, so lanes of the ego's direction lie at
d > 0 and oncoming lanes at d < 0.

Every line carries its OpenLane category (DESIGN.md, "Lane categories") and a track id that
stays the same along the whole road. A merge or split is an *extra lane* on the right:
it opens over a taper (the lines right of it diverge), runs at full width, and closes again
(they converge); the line that separates it from the through lanes starts and ends with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lanelab.lanes import LEFT_CURBSIDE, RIGHT_CURBSIDE

WHITE, YELLOW = "white", "yellow"
# (colour, dashed, double) -> OpenLane category id
_CATEGORY = {
    (WHITE, True, False): 1, (WHITE, False, False): 2, (WHITE, True, True): 3, (WHITE, False, True): 4,
    (YELLOW, True, False): 7, (YELLOW, False, False): 8, (YELLOW, True, True): 9, (YELLOW, False, True): 10,
}
LINE_WIDTH_M = 0.15
DOUBLE_GAP_M = 0.12  # between the two stripes of a double line
# An extra lane's separating line is painted once the lane is this far open (fraction of the taper).
SEPARATOR_TAPER_FRACTION = 0.25


@dataclass(frozen=True)
class Marking:
    """How a line is painted. dash/gap in metres; dash None is a solid line."""

    color: str
    dash: float | None = None
    gap: float = 0.0
    double: bool = False
    width: float = LINE_WIDTH_M

    @property
    def category(self) -> int:
        return _CATEGORY[(self.color, self.dash is not None, self.double)]

    @property
    def period(self) -> float:
        return (self.dash or 0.0) + self.gap

    @property
    def paint_share(self) -> float:
        """Fraction of the line's length that is painted."""
        return 1.0 if self.dash is None else self.dash / self.period

    def stripe_offsets(self) -> tuple[float, ...]:
        """Lateral offsets of the painted stripes from the line's centre."""
        half = (self.width + DOUBLE_GAP_M) / 2
        return (-half, half) if self.double else (0.0,)

    def painted(self, s: np.ndarray) -> np.ndarray:
        """(N,) bool: is arc length s (N,) on a dash? Every dash starts at a multiple of the period."""
        if self.dash is None:
            return np.ones(np.shape(s), bool)
        return np.mod(s, self.period) < self.dash


@dataclass(frozen=True)
class Line:
    """A lane boundary along the road: a painted line, or a curbside (the asphalt edge).

    offset: d where no extra lane is open; lines right of the extra lanes
    (``follows_extra``) move right by the open width. The line exists for start <= s <= end.
    """

    track_id: int
    category: int
    offset: float
    marking: Marking | None = None
    follows_extra: bool = False
    start: float = -math.inf
    end: float = math.inf


@dataclass(frozen=True)
class Lane:
    """A through lane: centre offset d and travel direction (+1 along s, -1 oncoming)."""

    offset: float
    direction: int
    width: float


@dataclass(frozen=True)
class ExtraLane:
    """A lane added on the right at ``start`` (split) and dropped again at ``end`` (merge)."""

    start: float
    end: float
    taper: float
    width: float

    def open_width(self, s: np.ndarray) -> np.ndarray:
        """(N,) width of the lane at arc length s (N,): smooth 0 -> width -> 0."""
        return self.width * _smoothstep((s - self.start) / self.taper) * _smoothstep((self.end - s) / self.taper)


@dataclass(frozen=True)
class Band:
    """A strip beside the asphalt: from ``inner`` to ``outer`` metres beyond the curbside on ``side``."""

    side: int  # -1 left, +1 right
    inner: float
    outer: float
    height: float
    material: str


@dataclass(frozen=True)
class CrossSection:
    environment: str
    lanes: tuple[Lane, ...]  # through lanes, left to right
    lines: tuple[Line, ...]
    extra_lanes: tuple[ExtraLane, ...]
    bands: tuple[Band, ...]
    curb_height: float  # raised curbs (urban); 0 = flush edge

    def extra_width(self, s: np.ndarray) -> np.ndarray:
        """(N,) total open width of the extra lanes at arc length s (N,)."""
        s = np.asarray(s, float)
        return sum((lane.open_width(s) for lane in self.extra_lanes), np.zeros_like(s))

    def line_offset(self, line: Line, s: np.ndarray) -> np.ndarray:
        """(N,) lateral offset of ``line`` at arc length s (N,)."""
        s = np.asarray(s, float)
        return line.offset + (self.extra_width(s) if line.follows_extra else np.zeros_like(s))

    def curbside(self, side: int) -> Line:
        category = LEFT_CURBSIDE if side < 0 else RIGHT_CURBSIDE
        return next(line for line in self.lines if line.category == category)

    def ego_lanes(self) -> list[int]:
        """Indices into ``lanes`` of the lanes in the driving direction."""
        return [i for i, lane in enumerate(self.lanes) if lane.direction > 0]


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


class _Lines:
    """Collects lines and numbers them in order, so track ids are stable for a layout."""

    def __init__(self) -> None:
        self.lines: list[Line] = []

    def add(self, offset: float, marking: Marking | None = None, category: int | None = None, **kw) -> None:
        category = marking.category if category is None else category
        self.lines.append(Line(len(self.lines) + 1, category, offset, marking, **kw))

    def separators(self, offset: float, marking: Marking, extra_lanes: tuple[ExtraLane, ...]) -> None:
        """The line between the through lanes and each extra lane, painted while it is open."""
        for extra in extra_lanes:
            margin = SEPARATOR_TAPER_FRACTION * extra.taper
            self.add(offset, marking, start=extra.start + margin, end=extra.end - margin)


def _through_lanes(num_lanes: int, num_opposite: int, width: float) -> tuple[Lane, ...]:
    oncoming = [Lane(-(k + 0.5) * width, -1, width) for k in reversed(range(num_opposite))]
    return tuple(oncoming + [Lane((k + 0.5) * width, +1, width) for k in range(num_lanes)])


def _verges(inner_material: str, inner_width: float, height: float, terrain_width: float) -> tuple[Band, ...]:
    return tuple(
        band
        for side in (-1, 1)
        for band in (
            Band(side, 0.0, inner_width, height, inner_material),
            Band(side, inner_width, inner_width + terrain_width, height, "terrain"),
        )
    )


def highway(num_lanes: int, lane_width: float, extra_lanes: tuple[ExtraLane, ...] = (),
            terrain_width: float = 40.0) -> CrossSection:
    """A divided highway carriageway: yellow left edge, 3/9 m dashes, white right edge, shoulders."""
    dashed, right_edge = Marking(WHITE, 3.0, 9.0), Marking(WHITE, width=0.2)
    right = num_lanes * lane_width
    lines = _Lines()
    lines.add(-1.0, category=LEFT_CURBSIDE)
    lines.add(0.0, Marking(YELLOW, width=0.2))
    for k in range(1, num_lanes):
        lines.add(k * lane_width, dashed)
    lines.separators(right, dashed, extra_lanes)
    lines.add(right, right_edge, follows_extra=True)
    lines.add(right + 2.5, category=RIGHT_CURBSIDE, follows_extra=True)
    return CrossSection("highway", _through_lanes(num_lanes, 0, lane_width), tuple(lines.lines),
                        tuple(extra_lanes), _verges("grass", 6.0, 0.0, terrain_width), 0.0)


def two_way(environment: str, num_lanes: int, num_opposite: int, lane_width: float,
            extra_lanes: tuple[ExtraLane, ...] = (), double_centre: bool = True,
            terrain_width: float = 40.0) -> CrossSection:
    """An urban street (curbs, sidewalks, 3/5 m dashes) or a rural road (edge lines, grass verges)."""
    urban = environment == "urban"
    dashed = Marking(WHITE, 3.0, 5.0) if urban else Marking(WHITE, 3.0, 9.0)
    centre = Marking(YELLOW, double=True) if double_centre or urban else Marking(YELLOW, 3.0, 9.0)
    margin = 0.3 if urban else 0.6  # gutter (urban) or paved shoulder (rural) beyond the last lane
    left, right = -num_opposite * lane_width, num_lanes * lane_width
    lines = _Lines()
    lines.add(left - margin, category=LEFT_CURBSIDE)
    if not urban:
        lines.add(left, Marking(WHITE))
    for k in reversed(range(1, num_opposite)):
        lines.add(-k * lane_width, dashed)
    lines.add(0.0, centre)
    for k in range(1, num_lanes):
        lines.add(k * lane_width, dashed)
    lines.separators(right, dashed, extra_lanes)
    if not urban:
        lines.add(right, Marking(WHITE), follows_extra=True)
    lines.add(right + margin, category=RIGHT_CURBSIDE, follows_extra=True)
    verges = _verges("sidewalk", 3.5, 0.15, terrain_width) if urban else _verges("grass", 4.0, 0.0, terrain_width)
    return CrossSection(environment, _through_lanes(num_lanes, num_opposite, lane_width), tuple(lines.lines),
                        tuple(extra_lanes), verges, 0.15 if urban else 0.0)


@dataclass(frozen=True)
class _ExtraLaneStyle:
    probability: float  # that a stretch of road has an extra lane
    taper_m: tuple[float, float]
    full_m: tuple[float, float]  # length at full width
    spacing_m: tuple[float, float]  # between two stretches


_EXTRA_LANE_STYLE = {
    "highway": _ExtraLaneStyle(0.8, (60.0, 120.0), (150.0, 400.0), (150.0, 600.0)),
    "urban": _ExtraLaneStyle(0.5, (20.0, 40.0), (60.0, 150.0), (80.0, 300.0)),
    "rural": _ExtraLaneStyle(0.35, (30.0, 60.0), (80.0, 200.0), (150.0, 500.0)),
}


def random_cross_section(rng: np.random.Generator, environment: str, num_lanes: int, lane_width: float,
                         start: float, end: float, min_radius: float) -> CrossSection:
    """A layout for ``environment`` with extra lanes scattered over [start, end] of arc length."""
    style = _EXTRA_LANE_STYLE[environment]
    extra, s = [], start + rng.uniform(-200.0, 200.0)
    while s < end:
        taper, full = rng.uniform(*style.taper_m), rng.uniform(*style.full_m)
        if rng.random() < style.probability:
            extra.append(ExtraLane(s, s + 2 * taper + full, taper, lane_width))
        s += 2 * taper + full + rng.uniform(*style.spacing_m)
    # Verges narrower than half the tightest radius never fold over on the inside of a curve.
    terrain = min(40.0, 0.4 * min_radius)
    if environment == "highway":
        return highway(num_lanes, lane_width, tuple(extra), terrain)
    num_opposite = min(num_lanes, 3)
    return two_way(environment, num_lanes, num_opposite, lane_width, tuple(extra),
                   double_centre=bool(rng.random() < 0.5), terrain_width=terrain)
