"""Scenery beside the road, as static boxes: barriers and guardrails, buildings, trees.

Placed relative to the curbsides, so it follows merges and splits. Besides looking like a
highway, a street or a country road, scenery hides the road on the inside of curves, and the
ground truth marks the lane points it hides (:mod:`labels`).
"""

from __future__ import annotations

import numpy as np

from data_ingest.synth.boxes import Boxes, make_boxes
from data_ingest.synth.road import Road

SEGMENT_M = 8.0  # of barriers and guardrails, short enough to follow curves
CONCRETE, STEEL = (160.0, 162.0, 165.0), (175.0, 180.0, 185.0)
TRUNK, CROWNS = (40.0, 60.0, 85.0), np.array([(40, 95, 50), (35, 80, 45), (50, 110, 70)], float)
FACADES = np.array([(150, 175, 200), (70, 80, 140), (170, 170, 170), (200, 205, 210), (110, 120, 130),
                    (120, 150, 180)], float)


def scenery(rng: np.random.Generator, road: Road) -> Boxes:
    """The static boxes along ``road`` in the style of its environment."""
    environment = road.cross_section.environment
    sidewalk = road.cross_section.bands[0].outer  # the first band beside each curbside
    if environment == "highway":
        parts = [_along_edge(road, -1, 0.3, 0.6, 0.0, 0.85, CONCRETE),  # median barrier
                 _along_edge(road, +1, 1.0, 1.15, 0.45, 0.8, STEEL),  # guardrail
                 _trees(rng, road, +1, (sidewalk + 4.0, sidewalk + 20.0), (15.0, 60.0)),
                 _trees(rng, road, -1, (sidewalk + 4.0, sidewalk + 20.0), (15.0, 60.0))]
    elif environment == "urban":
        parts = [_buildings(rng, road, side, sidewalk) for side in (-1, 1)]
    else:
        parts = [_trees(rng, road, side, (sidewalk + 1.0, sidewalk + 15.0), (8.0, 40.0)) for side in (-1, 1)]
    return Boxes.concat([p for p in parts if len(p)])


def _beside(road: Road, side: int, s: np.ndarray, inner: np.ndarray,
            outer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lateral (left, right) offsets at s (...) of a strip from ``inner`` to ``outer`` metres beyond a curbside."""
    edge = road.cross_section.line_offset(road.cross_section.curbside(side), s)
    near, far = edge + side * inner, edge + side * outer
    return (far, near) if side < 0 else (near, far)


def _along_edge(road: Road, side: int, inner: float, outer: float, bottom: float, top: float,
                color: tuple) -> Boxes:
    start = np.arange(0.0, road.length - SEGMENT_M, SEGMENT_M)
    s = np.stack([start, start + SEGMENT_M], axis=1)
    left, right = _beside(road, side, s, inner, outer)
    return make_boxes(s, left, right, bottom, top, color, key=start)


def _positions(rng: np.random.Generator, road: Road, spacing: tuple[float, float]) -> np.ndarray:
    steps = rng.uniform(*spacing, size=int(road.length / spacing[0]) + 1)
    s = np.cumsum(steps) - rng.uniform(0, spacing[1])
    return s[(s > 0) & (s < road.length - 20.0)]


def _trees(rng: np.random.Generator, road: Road, side: int, lateral: tuple[float, float],
           spacing: tuple[float, float]) -> Boxes:
    """A trunk and a crown per tree."""
    s = _positions(rng, road, spacing)
    n = len(s)
    crown = rng.uniform(2.5, 4.5, n)
    beyond = rng.uniform(*lateral, n) + crown / 2
    height = rng.uniform(3.0, 6.0, n)
    trunk_l, trunk_r = _beside(road, side, s, beyond - 0.2, beyond + 0.2)
    crown_l, crown_r = _beside(road, side, s, beyond - crown / 2, beyond + crown / 2)
    key = s - crown / 2
    trunks = make_boxes(np.stack([s - 0.2, s + 0.2], 1), trunk_l, trunk_r, 0.0, 2.5, TRUNK, key=key)
    crowns = make_boxes(np.stack([s - crown / 2, s + crown / 2], 1), crown_l, crown_r, 2.0, 2.0 + height,
                        CROWNS[rng.integers(len(CROWNS), size=n)], key=key, layer=1)
    return Boxes.concat([trunks, crowns])


def _buildings(rng: np.random.Generator, road: Road, side: int, sidewalk: float) -> Boxes:
    """A row of blocks with gaps, set back from the sidewalk."""
    lengths = rng.uniform(12.0, 35.0, int(road.length / 12.0) + 1)
    starts = np.cumsum(lengths + rng.uniform(2.0, 10.0, len(lengths))) - lengths - rng.uniform(0, 30.0)
    keep = (starts > 0) & (starts + lengths < road.length)
    starts, lengths = starts[keep], lengths[keep]
    n = len(starts)
    s = np.stack([starts, starts + lengths], axis=1)
    setback = sidewalk + rng.uniform(0.5, 3.0, n)[:, None]
    left, right = _beside(road, side, s, setback, setback + rng.uniform(10.0, 20.0, n)[:, None])
    return make_boxes(s, left, right, 0.0, rng.uniform(6.0, 30.0, n), FACADES[rng.integers(len(FACADES), size=n)],
                      key=starts)
