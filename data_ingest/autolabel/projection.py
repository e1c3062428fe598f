"""2D lane detections onto the road surface (SparseLaneSTP, supplementary E, "Projection to 3D").

The ray through each detection point (from the camera centre, through the pixel) meets the
road surface of :mod:`~data_ingest.autolabel.surface` where its quadratic says. Only the
near points are kept (camera depths within ``projection_range_m``, the paper's "first
segments"), where the surface and the pixels are accurate, and of them those whose lateral
offset ``d`` is known to ``max_point_std_m``: its standard deviation follows from the
detector's pixel noise: a pixel
across the image moves a ground point by depth / f sideways, a pixel down the image moves
it along its ray, which is sideways by depth / f times x / h (its lateral distance from the
camera over the camera's height above it, camera x over camera y of the point). Far points
and the outer lines therefore weigh less in the tracker.

A detection becomes an :class:`Observation`: its offsets resampled at the tracker's node
grid (every ``node_spacing_m`` of arc length), so a detector that reports a point per pixel
row weighs as much per metre as one that reports a point per metre.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from data_ingest.autolabel.surface import RoadSurface
from data_ingest.ingest.messages import Detection2D
from lanelab.geometry.camera import pixel_rays

MIN_NODES = 3  # a detection covering fewer nodes says nothing about a line's direction
SURFACE_LOOKAHEAD = 3.0  # segments tried per ray: up to this many times the far projection range ahead


@dataclass(frozen=True)
class Observation:
    """One detection on the road surface: nodes (M,) int, consecutive node indices (arc length
    ``node * node_spacing_m``); d (M,) lateral offsets and sigma (M,) their standard deviations,
    metres; its category and score; the frame it was seen in."""

    frame: int
    nodes: np.ndarray
    d: np.ndarray
    sigma: np.ndarray
    category: int
    score: float


def project_detections(
    surface: RoadSurface,
    frame: int,
    detections: Sequence[Detection2D],
    K: np.ndarray,
    T_world_lane: np.ndarray,
    T_lane_cam: np.ndarray,
    projection_range_m: tuple[float, float],
    pixel_noise_px: float,
    max_point_std_m: float,
    node_spacing_m: float,
    min_score: float = 0.0,
) -> list[Observation]:
    """The observations of one frame's detections: pose ``frame`` of the surface's trajectory,
    T_world_lane (4, 4), with its camera K (3, 3), T_lane_cam (4, 4)."""
    kept = [det for det in detections if det.score >= min_score and len(det.uv) >= 2]
    if not kept:
        return []
    near, far = projection_range_m
    uv = np.concatenate([det.uv for det in kept])
    owner = np.repeat(np.arange(len(kept)), [len(det.uv) for det in kept])
    rays_cam = pixel_rays(torch.from_numpy(uv), torch.from_numpy(K)).numpy()  # (P, 3), camera depth 1
    T_world_cam = T_world_lane @ T_lane_cam
    R, origin = T_world_cam[:3, :3], T_world_cam[:3, 3]
    s_here = surface.frame_s[frame]
    segments = surface.segments_between(s_here - far, s_here + SURFACE_LOOKAHEAD * far)
    points, s, d, valid = surface.intersect(origin, rays_cam @ R.T, segments)
    depth = (points - origin) @ R[:, 2]
    with np.errstate(invalid="ignore"):
        valid &= (depth >= near) & (depth <= far)
    sigma = _lateral_sigma(points - origin, T_world_lane[:3, :3], pixel_noise_px / K[0, 0])
    valid &= sigma <= max_point_std_m
    observations = []
    for k, det in enumerate(kept):
        mine = valid & (owner == k)
        observation = _on_nodes(frame, s[mine], d[mine], sigma[mine], det, node_spacing_m)
        if observation is not None:
            observations.append(observation)
    return observations


def _lateral_sigma(rays: np.ndarray, R_world_lane: np.ndarray, radians_per_pixel_noise: float) -> np.ndarray:
    """(P,) standard deviation of the lateral offset of ground points hit by rays (P, 3) (camera
    to point, world frame) for the given pixel noise in radians.

    Across the ray, the noise moves the point by length * noise sideways; along it (the ray
    tilts towards or away from the road), by length * noise / sin(grazing angle), of which the
    share across the road is the ray's lateral over its horizontal direction.
    """
    length = np.linalg.norm(rays, axis=1)
    unit = rays / length[:, None]
    lateral, forward, normal = (unit @ R_world_lane[:, k] for k in range(3))
    grazing = np.maximum(np.abs(normal), 1e-3)
    across = np.abs(lateral) / np.maximum(np.hypot(lateral, forward), 1e-9)
    return radians_per_pixel_noise * length * np.sqrt(1 + (across / grazing) ** 2)


def _on_nodes(frame: int, s: np.ndarray, d: np.ndarray, sigma: np.ndarray, det: Detection2D,
              node_spacing_m: float) -> Observation | None:
    """A detection's points (P,) resampled at the nodes within its arc-length extent, in order
    of arc length; None when it covers too few nodes or repeats an arc length."""
    if len(s) < 2:
        return None
    order = np.argsort(s)
    s, d, sigma = s[order], d[order], sigma[order]
    if np.any(np.diff(s) <= 0):
        return None
    nodes = np.arange(np.ceil(s[0] / node_spacing_m), np.floor(s[-1] / node_spacing_m) + 1).astype(np.int64)
    if len(nodes) < MIN_NODES:
        return None
    at = nodes * node_spacing_m
    return Observation(frame, nodes, np.interp(at, s, d), np.interp(at, s, sigma), int(det.category),
                       float(det.score))
