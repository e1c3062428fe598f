"""The ego vehicle: drives a lane at constant speed, wandering a little within it, and may change lanes.

Its pose is ROS ``base_link`` (x forward, y left, z up) in ``odom``: on the road surface
under the rear axle, heading along the road plus the wander's yaw, pitched and rolled
with the surface. The pose is a smooth function of time, so it can be sampled at any rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from data_ingest.synth.road import Road
from lanelab.geometry.transforms import euler_to_rotation, make_transform

LANE_CHANGE_PROBABILITY = 0.5  # per drive, where there is a neighbouring lane
LANE_CHANGE_S = (3.0, 6.0)  # how long one takes


@dataclass(frozen=True)
class Wander:
    """Lateral offset from the lane centre: a sum of slow sines, amplitudes (m), frequencies (Hz), phases."""

    amplitude: tuple[float, ...] = ()
    frequency: tuple[float, ...] = ()
    phase: tuple[float, ...] = ()

    @classmethod
    def random(cls, rng: np.random.Generator, max_offset: float = 0.3, terms: int = 3) -> Wander:
        return cls(tuple(rng.uniform(0.4, 1.0, terms) * max_offset / terms),
                   tuple(rng.uniform(1 / 40, 1 / 8, terms)), tuple(rng.uniform(0, 2 * np.pi, terms)))

    def offset(self, t: np.ndarray) -> np.ndarray:
        """(...) lateral offset (m, positive right) at times t (...) in seconds."""
        return sum((a * np.sin(2 * np.pi * f * t + p) for a, f, p in self._terms()), np.zeros_like(t))

    def rate(self, t: np.ndarray) -> np.ndarray:
        """(...) d offset / dt (m/s)."""
        return sum((a * 2 * np.pi * f * np.cos(2 * np.pi * f * t + p) for a, f, p in self._terms()), np.zeros_like(t))

    def _terms(self):
        return zip(self.amplitude, self.frequency, self.phase)


@dataclass(frozen=True)
class LaneChange:
    """A move of ``shift`` metres (positive right) starting at ``start`` and taking ``duration`` seconds."""

    start: float
    duration: float
    shift: float

    def offset(self, t: np.ndarray) -> np.ndarray:
        """(...) lateral offset gained by times t (...): a half cosine, so the yaw starts and ends at 0."""
        x = np.clip((np.asarray(t, float) - self.start) / self.duration, 0.0, 1.0)
        return self.shift * (1 - np.cos(np.pi * x)) / 2

    def rate(self, t: np.ndarray) -> np.ndarray:
        x = (np.asarray(t, float) - self.start) / self.duration
        inside = (x > 0) & (x < 1)
        return np.where(inside, self.shift * np.pi / (2 * self.duration) * np.sin(np.pi * np.clip(x, 0, 1)), 0.0)


class Ego:
    """The ego driving ``road.cross_section.lanes[lane]`` from arc length ``start_s`` at ``speed`` m/s."""

    def __init__(self, road: Road, lane: int, start_s: float, speed: float, wander: Wander = Wander(),
                 lane_changes: tuple[LaneChange, ...] = ()) -> None:
        self.road = road
        self.lane = lane
        self.lane_offset = road.cross_section.lanes[lane].offset
        self.speed = speed
        self.wander = wander
        self.lane_changes = lane_changes
        self._start = road.travelled(start_s, self.lane_offset)

    def place(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Road coordinates (s, d), each (...), of base_link at times t (...) in seconds.

        Progress is measured along the first lane: after a change on a curve, the speed is off by
        the curvature times the lane width (a few per cent at most).
        """
        t = np.asarray(t, float)
        s = self.road.s_after(self._start + self.speed * t, self.lane_offset)
        changes = sum((change.offset(t) for change in self.lane_changes), np.zeros_like(t))
        return s, self.lane_offset + changes + self.wander.offset(t)

    def lateral_rate(self, t: np.ndarray) -> np.ndarray:
        """(...) d offset / dt (m/s) at times t (...)."""
        t = np.asarray(t, float)
        return self.wander.rate(t) + sum((change.rate(t) for change in self.lane_changes), np.zeros_like(t))

    def pose(self, t: np.ndarray) -> np.ndarray:
        """T_world_base (..., 4, 4) at times t (...) in seconds."""
        t = np.asarray(t, float)
        s, d = self.place(t)
        # Drifting right (d growing) turns the nose right: negative yaw in ROS.
        yaw = self.road.heading(s) - np.arctan2(self.lateral_rate(t), self.speed)
        pitch = -np.arctan(self.road.grade(s))  # ROS pitch is positive nose-down
        roll = self.road.bank(s)  # positive bank lowers the right side, as a positive roll does
        R = euler_to_rotation(*(torch.from_numpy(np.asarray(a, float)) for a in (roll, pitch, yaw)))
        return make_transform(R, torch.from_numpy(self.road.surface(s, d))).numpy()



def plan_lane_change(rng: np.random.Generator, ego: Ego, duration: float) -> tuple[LaneChange, ...]:
    """At most one change to a neighbouring lane of the ego's direction, at a random time of the drive."""
    lanes = ego.road.cross_section.lanes
    targets = [k for k in (ego.lane - 1, ego.lane + 1) if 0 <= k < len(lanes) and lanes[k].direction > 0]
    wanted, length, start, pick = rng.random(), rng.uniform(*LANE_CHANGE_S), rng.random(), rng.integers(2)
    if not targets or wanted > LANE_CHANGE_PROBABILITY or duration < length + 2.0:
        return ()
    target = lanes[targets[pick % len(targets)]]
    return (LaneChange(1.0 + start * (duration - length - 2.0), length, target.offset - ego.lane_offset),)
