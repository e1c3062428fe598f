"""Ground truth of a frame's lanes, as every model is trained and scored on it.

Every lane is resampled at a fixed y grid (S,) (OpenLane's, PersFormer's and Bi²Lane's anchor
style): x and z by linear interpolation of the labelled polyline, visibility 1 where y lies
inside the lane's y range and the interpolated label visibility is above 0.5 (PersFormer's
``resample_laneline_in_y_with_vis``), else 0. Outside its y range a lane's x and z hold their
end values (np.interp); they carry no meaning there and the visibility of 0 says so. Models
that predict curves (SparseLaneSTP's Catmull-Rom lanes) sample them at the same grid.

A lane is kept when at least two of its grid samples are visible; the others (wholly occluded,
out of range, single points) carry nothing to learn.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from lanelab.lanes import Lane

# Keys with one row per lane: the collate pads these to a fixed number of lanes.
LANE_KEYS = ("gt_x", "gt_z", "gt_vis", "gt_category", "gt_track_id")

VISIBLE = 0.5  # interpolated label visibility above which a grid sample counts as visible


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
    """Turns a frame's lanes into targets at the resampling grid y (S,), metres, ascending."""

    y: np.ndarray

    def __call__(self, lanes: Sequence[Lane]) -> dict[str, np.ndarray]:
        """L kept lanes -> gt_x, gt_z, gt_vis (L, S) float32; gt_category, gt_track_id (L,) int64."""
        lanes = [lane for lane in lanes if len(lane.points) >= 2]
        grid = np.array([resample_lane(lane.points, lane.visibility, self.y) for lane in lanes])
        grid = grid.reshape(len(lanes), len(self.y), 3)
        keep = grid[..., 2].sum(-1) >= 2
        return {
            "gt_x": grid[keep, :, 0].astype(np.float32),
            "gt_z": grid[keep, :, 1].astype(np.float32),
            "gt_vis": grid[keep, :, 2].astype(np.float32),
            "gt_category": np.array([lane.category for lane in lanes], np.int64)[keep],
            "gt_track_id": np.array([lane.track_id for lane in lanes], np.int64)[keep],
        }
