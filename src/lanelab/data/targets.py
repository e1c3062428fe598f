"""Ground truth of a frame's lanes, prepared for both models.

- Anchor-style (Bi²Lane, PersFormer): every lane resampled at a fixed y grid (S,): x and z by
  linear interpolation of the labelled polyline, visibility 1 where y lies inside the lane's y
  range and the interpolated label visibility is above 0.5 (PersFormer's
  ``resample_laneline_in_y_with_vis``), else 0.
  Outside its y range a lane's x and z hold their end values (np.interp); they carry no
  meaning there and the visibility of 0 says so.
- Catmull-Rom (SparseLaneSTP): M control points (x, y, z, visibility) at fixed y in
  [y_start, y_end], x and z fitted by least squares to every label point in that range
  (:func:`lanelab.geometry.fit_control_points`); the control points' visibility is the
  resampled visibility at their y, so the curve through them follows the lane's visibility.

A lane is kept when at least two of its grid samples are visible and its control points could
be fitted; the others (wholly occluded, out of range, single points) carry nothing to learn.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np
import torch

from lanelab.geometry import control_point_y, fit_control_points

# Keys with one row per lane: the collate pads these to a fixed number of lanes.
LANE_KEYS = ("gt_x", "gt_z", "gt_vis", "gt_ctrl", "gt_category", "gt_track_id")

VISIBLE = 0.5  # interpolated label visibility above which a grid sample counts as visible


class Lane(Protocol):
    """What targets read of a lane (``clip_store.LaneRecord`` is one)."""

    track_id: int
    category: int
    points: np.ndarray  # (P, 3) x, y, z in the lane frame, y ascending
    visibility: np.ndarray  # (P,) in [0, 1]


def resample_lane(points: np.ndarray, visibility: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A lane at longitudinal positions y (S,) -> (S, 3) columns x, z, visibility (0 or 1)."""
    ly = points[:, 1]
    x = np.interp(y, ly, points[:, 0])
    z = np.interp(y, ly, points[:, 2])
    inside = (y >= ly[0]) & (y <= ly[-1])
    visible = inside & (np.interp(y, ly, visibility) > VISIBLE)
    return np.stack([x, z, visible.astype(np.float64)], axis=-1)


@dataclass(frozen=True)
class LaneTargets:
    """Turns a frame's lanes into fixed-y and Catmull-Rom targets.

    y: (S,) the resampling grid in metres, ascending.
    num_control_points: M. control_y_range: (y_start, y_end) of the control points.
    """

    y: np.ndarray
    num_control_points: int
    control_y_range: tuple[float, float]

    def __call__(self, lanes: Sequence[Lane]) -> dict[str, np.ndarray]:
        """L kept lanes -> gt_x, gt_z, gt_vis (L, S) float32; gt_ctrl (L, M, 4) float32 (x, y, z,
        visibility); gt_category, gt_track_id (L,) int64."""
        lanes = [lane for lane in lanes if len(lane.points) >= 2]
        grid = np.array([resample_lane(lane.points, lane.visibility, self.y) for lane in lanes])
        grid = grid.reshape(len(lanes), len(self.y), 3)
        ctrl = self._control_points(lanes)
        keep = (grid[..., 2].sum(-1) >= 2) & np.isfinite(ctrl).all(axis=(-1, -2))
        return {
            "gt_x": grid[keep, :, 0].astype(np.float32),
            "gt_z": grid[keep, :, 1].astype(np.float32),
            "gt_vis": grid[keep, :, 2].astype(np.float32),
            "gt_ctrl": ctrl[keep].astype(np.float32),
            "gt_category": np.array([lane.category for lane in lanes], np.int64)[keep],
            "gt_track_id": np.array([lane.track_id for lane in lanes], np.int64)[keep],
        }

    def _control_points(self, lanes: Sequence[Lane]) -> np.ndarray:
        """(L, M, 4) control points x, y, z, visibility; NaN for lanes that cannot be fitted."""
        y_start, y_end = self.control_y_range
        cy = control_point_y(self.num_control_points, y_start, y_end, dtype=torch.float64).numpy()
        if not lanes:
            return np.zeros((0, self.num_control_points, 4))
        # Lanes have different numbers of points: pad with NaN, which the fit ignores.
        padded = np.full((len(lanes), max(len(lane.points) for lane in lanes), 3), np.nan)
        for i, lane in enumerate(lanes):
            padded[i, : len(lane.points)] = lane.points
        xz = fit_control_points(
            torch.from_numpy(padded[..., 1]), torch.from_numpy(padded[..., [0, 2]]),
            self.num_control_points, y_start, y_end,
        ).numpy()
        vis = np.stack([resample_lane(lane.points, lane.visibility, cy)[:, 2] for lane in lanes])
        return np.stack([xz[..., 0], np.broadcast_to(cy, vis.shape), xz[..., 1], vis], axis=-1)
