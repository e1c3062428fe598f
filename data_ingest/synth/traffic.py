"""Traffic: cars, vans and trucks driving the through lanes at constant speed.

Vehicles of one lane share its speed, so they never run into each other; vehicles in the
ego's lane start ahead of it and drive faster, and :meth:`Traffic.clear_of` leaves out any
that would still come near the ego (after a lane change), so none runs into it. Each
vehicle is a few boxes (:mod:`boxes`): underbody, body, cabin or cargo box, and lights.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from data_ingest.synth.boxes import ALL_BUT_BOTTOM, FRONT, REAR, Boxes, make_boxes
from data_ingest.synth.road import Road

TYPICAL_SPEED_MPS = {"highway": (25.0, 33.0), "rural": (15.0, 25.0), "urban": (8.0, 14.0)}
KINDS = ("car", "van", "truck")
KIND_MIX = {"highway": (0.65, 0.15, 0.20), "rural": (0.75, 0.15, 0.10), "urban": (0.80, 0.15, 0.05)}
# (length, width, height) ranges per kind, metres
KIND_SIZE = {"car": ((4.0, 4.9), (1.7, 1.9), (1.4, 1.55)),
             "van": ((4.8, 6.0), (1.9, 2.1), (2.1, 2.6)),
             "truck": ((10.0, 16.5), (2.45, 2.55), (3.5, 4.0))}
PAINTS = np.array([(235, 235, 235), (25, 25, 28), (170, 170, 175), (110, 110, 115), (40, 40, 170),
                   (140, 70, 30), (80, 40, 20), (40, 110, 60), (30, 150, 210), (60, 60, 120)], float)
CARGO_PAINTS = np.array([(225, 225, 225), (190, 195, 200), (60, 120, 200), (140, 60, 40)], float)
UNDERBODY, GLASS = (22.0, 22.0, 24.0), (75.0, 60.0, 55.0)
TAIL_LIGHT, HEAD_LIGHT = (40.0, 30.0, 210.0), (215.0, 240.0, 250.0)
EGO_CLEARANCE_M = 25.0  # vehicles in the ego's lane start at least this far ahead of it
# A vehicle that would ever come this close (centre to base_link) in the ego's lane is left out.
CLEAR_BEHIND_M, CLEAR_AHEAD_M, SAME_LANE_M = 12.0, 15.0, 2.5
MIN_GAP_M = 6.0  # bumper to bumper


@dataclass(frozen=True)
class Vehicle:
    """A vehicle driving along a lane at lateral offset ``lane_offset``.

    s: arc length of its centre at t = 0; speed (m/s, >= 0) along ``direction`` (+1 along s,
    -1 oncoming). color: BGR of its paint; cargo: BGR of a truck's cargo box.
    """

    lane_offset: float
    s: float
    speed: float
    direction: int = 1
    kind: str = "car"
    length: float = 4.5
    width: float = 1.8
    height: float = 1.5
    color: tuple[float, float, float] = (40.0, 40.0, 170.0)
    cargo: tuple[float, float, float] = (225.0, 225.0, 225.0)

    @classmethod
    def in_lane(cls, road: Road, lane: int, s: float, speed: float = 0.0, kind: str = "car", **kw) -> Vehicle:
        """A vehicle in ``road.cross_section.lanes[lane]``, driving that lane's way; sizes from the kind."""
        size = {key: float(np.mean(r)) for key, r in zip(("length", "width", "height"), KIND_SIZE[kind])}
        info = road.cross_section.lanes[lane]
        return cls(info.offset, s, speed, info.direction, kind, **{**size, **kw})


def _parts(v: Vehicle) -> list[tuple]:
    """The boxes of one vehicle in its own frame: (u0, u1, v0, v1, z0, z1, color, layer, emissive, faces).

    u runs forward from the centre, v to the right; decals face rear or front only.
    """
    L, W, H = v.length / 2, v.width / 2, v.height  # half length, half width, height
    faces = ALL_BUT_BOTTOM
    rear = np.eye(6, dtype=bool)[REAR]
    front = np.eye(6, dtype=bool)[FRONT]
    ride = 0.7 if v.kind == "truck" else 0.3
    parts = [(-L + 0.4, L - 0.4, -W + 0.1, W - 0.1, 0.0, ride + 0.05, UNDERBODY, 0, False, faces)]
    if v.kind == "car":
        parts += [(-L, L, -W, W, ride, 0.95, v.color, 1, False, faces),
                  (-0.64 * L, 0.36 * L, -W + 0.12, W - 0.12, 0.95, H, GLASS, 2, False, faces)]
        glass_z = None
    elif v.kind == "van":
        parts += [(-L, L, -W, W, ride, H, v.color, 1, False, faces)]
        glass_z = (1.25, H - 0.15)
    else:
        parts += [(L - 2.3, L, -W, W, ride, 3.0, v.color, 1, False, faces),
                  (-L, L - 2.6, -W, W, ride + 0.2, H, v.cargo, 1, False, faces)]
        glass_z = (1.9, 2.8)
    if glass_z is not None:
        parts.append((L, L + 0.03, -W + 0.12, W - 0.12, *glass_z, GLASS, 3, False, front))
    light_z = 0.75 if v.kind == "car" else 1.0
    for v0, v1 in ((-W + 0.05, -W + 0.35), (W - 0.35, W - 0.05)):
        parts.append((-L - 0.03, -L, v0, v1, light_z - 0.08, light_z + 0.08, TAIL_LIGHT, 3, True, rear))
        parts.append((L, L + 0.03, v0, v1, light_z - 0.2, light_z - 0.08, HEAD_LIGHT, 3, True, front))
    return parts


class Traffic:
    """The vehicles of a drive; :meth:`boxes` places them at a time."""

    def __init__(self, road: Road, vehicles: Sequence[Vehicle]) -> None:
        self.road = road
        self.vehicles = list(vehicles)
        self._lane_offsets = sorted({v.lane_offset for v in self.vehicles})
        self._lane = np.array([self._lane_offsets.index(v.lane_offset) for v in self.vehicles], np.int64)
        # Past the road's end (oncoming vehicles yet to arrive) the distance runs on straight.
        self._start = np.array([road.travelled(min(v.s, road.length), v.lane_offset) + max(v.s - road.length, 0.0)
                                for v in self.vehicles])
        self._velocity = np.array([v.direction * v.speed for v in self.vehicles])
        self._sign = np.array([v.direction for v in self.vehicles], float)
        self._offset = np.array([v.lane_offset for v in self.vehicles])
        self._half_length = np.array([v.length / 2 for v in self.vehicles])
        rows = [(i, *part) for i, v in enumerate(self.vehicles) for part in _parts(v)]
        owner, u0, u1, v0, v1, z0, z1, color, layer, emissive, faces = zip(*rows) if rows else ((),) * 11
        self._owner = np.array(owner, np.int64)
        self._u = np.array([u0, u1], float).T.reshape(-1, 2)
        self._v = np.array([v0, v1], float).T.reshape(-1, 2)
        self._z = np.array([z0, z1], float).T.reshape(-1, 2)
        self._color = np.array(color, float).reshape(-1, 3)
        self._layer = np.array(layer, np.int64)
        self._emissive = np.array(emissive, bool)
        self._faces = np.array(faces, bool).reshape(-1, 6)

    def centres(self, t: np.ndarray) -> np.ndarray:
        """(..., V) arc length of every vehicle's centre at times t (...) in seconds; NaN off the road."""
        travelled = self._start + self._velocity * np.asarray(t, float)[..., None]
        s = np.full(travelled.shape, np.nan)
        for k, offset in enumerate(self._lane_offsets):
            mine = (self._lane == k) & (travelled >= 0) & (travelled <= self.road.travelled(self.road.length, offset))
            s[mine] = self.road.s_after(travelled[mine], offset)
        return s

    def clear_of(self, times: np.ndarray, s: np.ndarray, d: np.ndarray) -> Traffic:
        """This traffic without the vehicles that come near the ego in its lane, the ego being at road
        coordinates s, d (T,) at times (T,) in seconds (a lane change may lead it into any lane)."""
        gap = self.centres(times) - s[:, None]
        same_lane = np.abs(self._offset[None, :] - d[:, None]) < SAME_LANE_M
        with np.errstate(invalid="ignore"):
            conflict = (same_lane & (gap > -CLEAR_BEHIND_M) & (gap < CLEAR_AHEAD_M)).any(axis=0)
        return Traffic(self.road, [v for v, near in zip(self.vehicles, conflict) if not near])

    def boxes(self, t: float, s_min: float, s_max: float) -> Boxes:
        """The boxes of the vehicles whose centre is within [s_min, s_max] at time t (s)."""
        centre = self.centres(t)
        with np.errstate(invalid="ignore"):
            shown = (centre >= s_min) & (centre <= s_max)
        parts = shown[self._owner]
        owner = self._owner[parts]
        sign = self._sign[owner][:, None]
        s = centre[owner][:, None] + sign * self._u[parts]
        d = self._offset[owner][:, None] + sign * self._v[parts]
        # Turning a vehicle round (sign -1) rotates it: its rear faces +s and its left side +d.
        return make_boxes(s, d[:, 0], d[:, 1], self._z[parts, 0], self._z[parts, 1], self._color[parts],
                          key=centre[owner] - self._half_length[owner], layer=self._layer[parts],
                          emissive=self._emissive[parts], faces=self._faces[parts])


def random_vehicles(rng: np.random.Generator, road: Road, environment: str, density: float, ego_lane: int,
                    ego_s: float, ego_speed: float, duration_s: float) -> list[Vehicle]:
    """Vehicles in every through lane, ``density`` per 100 m of lane on average."""
    if density <= 0:
        return []
    spacing = 100.0 / density
    vehicles = []
    for index, lane in enumerate(road.cross_section.lanes):
        if index == ego_lane:
            speed, start = ego_speed * rng.uniform(1.03, 1.12), ego_s + EGO_CLEARANCE_M
        elif lane.direction > 0:
            speed, start = ego_speed * rng.uniform(0.85, 1.15), 0.0
        else:
            speed, start = rng.uniform(*TYPICAL_SPEED_MPS[environment]), 0.0
        # Oncoming vehicles that reach the ego's view during the drive may start past the road's end.
        end = road.length + (speed * duration_s if lane.direction < 0 else 0.0)
        s = start + rng.exponential(spacing / 2)
        while s < end:
            kind = KINDS[rng.choice(3, p=KIND_MIX[environment])]
            length, width, height = (rng.uniform(*r) for r in KIND_SIZE[kind])
            s += length / 2
            vehicles.append(Vehicle(lane.offset, s, speed, lane.direction, kind, length, width, height,
                                    tuple(PAINTS[rng.integers(len(PAINTS))]),
                                    tuple(CARGO_PAINTS[rng.integers(len(CARGO_PAINTS))])))
            s += length / 2 + MIN_GAP_M + rng.exponential(max(spacing - length - MIN_GAP_M, 1.0))
    return vehicles
