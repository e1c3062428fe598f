"""Per-frame labels: the tracked lines carried into each frame's lane frame (SparseLaneSTP,
supplementary E, "3D ground truth per frame").

A line's nodes are points of the road surface, ``surface.point(s, d)`` in the world frame;
frame t sees them through ``T_world_lane(t)^-1``. Each frame gets the part of every line from
y = 0 out to ``range_m`` ahead, while y grows (a lane is a function of y), with a visibility
per point: 0 where the point is outside the camera's image, where the line of sight from
the camera dips below the road surface (behind a crest), or, given an occluder mask, where
the mask covers its pixel.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from data_ingest.autolabel.surface import RoadSurface
from data_ingest.autolabel.tracker import Line
from lanelab.geometry.camera import in_image, project_lane_points
from lanelab.lanes import Lane

ARC_MARGIN = 1.6  # arc length looked at per metre of range: lanes curving away need more
BEHIND_M = 5.0  # nodes this far behind the ego are looked at, so a lane starts at y = 0
LINE_OF_SIGHT_SAMPLES = 24
CREST_TOLERANCE_M = 0.05
MIN_VISIBLE_POINTS = 2


def frame_labels(
    surface: RoadSurface,
    lines: Sequence[Line],
    node_spacing_m: float,
    frame: int,
    T_world_lane: np.ndarray,
    K: np.ndarray,
    T_lane_cam: np.ndarray,
    image_size: tuple[int, int],
    range_m: float,
    occluded: np.ndarray | None = None,
) -> list[Lane]:
    """The lanes of pose ``frame`` of the surface's trajectory: T_world_lane (4, 4) its pose, K
    (3, 3) and T_lane_cam (4, 4) its camera, image_size (width, height); occluded: (H, W) bool,
    True where something hides the road, or None."""
    s_here = surface.frame_s[frame]
    T_lane_world = np.linalg.inv(T_world_lane)
    camera = T_lane_cam[:3, 3]
    ground = _ground_profile(surface, T_lane_world, s_here, s_here + ARC_MARGIN * range_m)
    lanes = []
    for line in lines:
        s = line.nodes * node_spacing_m
        near = (s >= s_here - BEHIND_M) & (s <= s_here + ARC_MARGIN * range_m)
        if near.sum() < 2:
            continue
        world = surface.point(s[near], line.d[near])
        points = world @ T_lane_world[:3, :3].T + T_lane_world[:3, 3]
        points = points[_ahead_and_ascending(points[:, 1], range_m)]
        if len(points) < 2:
            continue
        visible = _in_view(points, K, T_lane_cam, image_size, occluded) & ~_behind_surface(points, camera, ground)
        if visible.sum() >= MIN_VISIBLE_POINTS:
            lanes.append(Lane(points.astype(np.float32), visible.astype(np.float32), line.category,
                              track_id=line.track_id))
    return lanes


def _ahead_and_ascending(y: np.ndarray, range_m: float) -> np.ndarray:
    """Indices of the points from the first with y >= 0 on, while y grows and stays within range."""
    ahead = np.flatnonzero(y >= 0)
    if not len(ahead):
        return ahead
    start = ahead[0]
    rising = np.concatenate([[True], np.diff(y[start:]) > 0]) & (y[start:] <= range_m)
    stop = start + (np.argmin(rising) if not rising.all() else len(rising))
    return np.arange(start, stop)


def _in_view(points: np.ndarray, K: np.ndarray, T_lane_cam: np.ndarray, image_size: tuple[int, int],
             occluded: np.ndarray | None) -> np.ndarray:
    """(P,) bool: the lane-frame points (P, 3) project into the image, onto no occluder."""
    uv, _, in_front = project_lane_points(torch.from_numpy(points), torch.from_numpy(K), torch.from_numpy(T_lane_cam))
    inside = (in_front & in_image(uv, *image_size)).numpy()
    if occluded is not None and inside.any():
        col, row = np.floor(uv.numpy()[inside]).astype(np.int64).T
        inside[np.flatnonzero(inside)] = ~occluded[row, col]
    return inside


def _ground_profile(surface: RoadSurface, T_lane_world: np.ndarray, s_from: float,
                    s_to: float) -> tuple[np.ndarray, ...]:
    """The surface ahead in a frame's lane frame, for line-of-sight tests: the cross-sections'
    y (C,) ascending, their centre x and z (C,), and their height change per metre to the right (C,)."""
    _, p, lateral = surface.cross_sections(s_from, s_to)
    p = p @ T_lane_world[:3, :3].T + T_lane_world[:3, 3]
    lateral = lateral @ T_lane_world[:3, :3].T
    keep = _ahead_and_ascending(p[:, 1], np.inf)
    if len(keep) and keep[0] > 0:
        keep = np.concatenate([[keep[0] - 1], keep])  # the cross-section behind the ego too
    p, lateral = p[keep], lateral[keep]
    return p[:, 1], p[:, 0], p[:, 2], lateral[:, 2] / lateral[:, 0]


def _behind_surface(points: np.ndarray, camera: np.ndarray, ground: tuple[np.ndarray, ...]) -> np.ndarray:
    """(P,) bool: the line of sight from the camera (3,) to each point (P, 3) dips below the road
    surface (a crest hides the point)."""
    y, x0, z0, bank = ground
    if len(y) < 2:
        return np.zeros(len(points), bool)
    f = np.linspace(0.0, 1.0, LINE_OF_SIGHT_SAMPLES + 2)[1:-1, None, None]  # ends excluded
    sight = camera + f * (points - camera)  # (F, P, 3)
    at = sight[..., 1]
    height = np.interp(at, y, z0) + (sight[..., 0] - np.interp(at, y, x0)) * np.interp(at, y, bank)
    return (sight[..., 2] < height - CREST_TOLERANCE_M).any(axis=0)
