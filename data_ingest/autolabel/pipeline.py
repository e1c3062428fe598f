"""The auto-labeling of one drive, stage after stage (SparseLaneSTP §4.1, supplementary E).

:func:`auto_label` takes a drive's frames (poses, cameras, 2D lane detections) in time order:

1. the road surface from the ego trajectory (:mod:`~data_ingest.autolabel.surface`);
2. each frame's detections met with it (:mod:`~data_ingest.autolabel.projection`);
3. accumulated and tracked into lines along the drive (:mod:`~data_ingest.autolabel.tracker`);
4. the lines carried into every frame (:mod:`~data_ingest.autolabel.frame_labels`).

A frame is labeled when its labels can reach ``reach_m`` ahead: the detections of the drive's
last frame reach ``projection_range_m[1]`` past its end, so the last frames, whose road
ahead the ego never drove, stay unlabeled (temporal history). :func:`check_trajectory`
refuses a trajectory that jumps or stops.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from data_ingest.autolabel.config import AutolabelConfig
from data_ingest.autolabel.frame_labels import frame_labels
from data_ingest.autolabel.projection import project_detections
from data_ingest.autolabel.surface import RoadSurface
from data_ingest.autolabel.tracker import MIN_OVERLAP_NODES, Line, LineTracker, Track
from data_ingest.ingest.messages import Detection2D
from lanelab.geometry.camera import in_image, project
from lanelab.lanes import Lane


class TrajectoryError(ValueError):
    """A trajectory that cannot carry a road surface (it jumps or does not move); says where."""


@dataclass(frozen=True)
class DriveFrames:
    """A drive's frames in time order: stamps (N,) int64 ns, K (N, 3, 3), T_lane_cam and
    T_world_lane (N, 4, 4), image sizes (N, 2) (width, height), detections[i] of frame i,
    occluded[i]: (H, W) bool mask of what hides the road in frame i, or None."""

    stamps: np.ndarray
    K: np.ndarray
    T_lane_cam: np.ndarray
    T_world_lane: np.ndarray
    image_size: np.ndarray
    detections: Sequence[Sequence[Detection2D]]
    occluded: Sequence[np.ndarray | None] | None = None


@dataclass(frozen=True)
class AutoLabels:
    """lanes[i]: frame i's labels ([] where unlabeled); labeled (N,) bool; the tracked lines."""

    lanes: list[list[Lane]]
    labeled: np.ndarray
    lines: list[Line]
    surface: RoadSurface


def check_trajectory(stamps: np.ndarray, T_world_lane: np.ndarray, cfg: AutolabelConfig) -> None:
    """Raise :class:`TrajectoryError` when the ego moves faster than ``max_speed_mps`` between
    two frames (a jump) or less than ``min_travel_m`` in all."""
    step = np.linalg.norm(np.diff(T_world_lane[:, :3, 3], axis=0), axis=1)
    dt = np.maximum(np.diff(stamps) * 1e-9, 1e-9)
    speed = step / dt
    if len(speed) and speed.max() > cfg.max_speed_mps:
        k = int(np.argmax(speed))
        raise TrajectoryError(f"the ego trajectory jumps {step[k]:.1f} m between the frames at "
                              f"{(stamps[k] - stamps[0]) * 1e-9:.2f} s and {(stamps[k + 1] - stamps[0]) * 1e-9:.2f} s "
                              f"({speed[k]:.0f} m/s > autolabel.max_speed_mps={cfg.max_speed_mps:g})")
    travel = float(step.sum())
    if travel < cfg.min_travel_m:
        raise TrajectoryError(f"the ego trajectory stops: {travel:.1f} m travelled in "
                              f"{(stamps[-1] - stamps[0]) * 1e-9:.1f} s (< autolabel.min_travel_m={cfg.min_travel_m:g}); "
                              "auto-labels need a drive")


def auto_label(drive: DriveFrames, cfg: AutolabelConfig) -> AutoLabels:
    """Auto-label a drive (see the module's docstring); the trajectory must pass check_trajectory."""
    check_trajectory(drive.stamps, drive.T_world_lane, cfg)
    surface = RoadSurface(drive.T_world_lane)
    T_world_cam = drive.T_world_lane @ drive.T_lane_cam
    near, far = cfg.projection_range_m
    spacing = cfg.node_spacing_m
    tracker = LineTracker(spacing, cfg.gate_m, cfg.confirm_hits, cfg.max_misses, cfg.merge_m, cfg.process_noise_m,
                          cfg.category_penalty_m)
    for t in range(len(drive.stamps)):
        observations = project_detections(surface, t, drive.detections[t], drive.K[t], drive.T_world_lane[t],
                                          drive.T_lane_cam[t], (near, far), cfg.pixel_noise_px, cfg.max_point_std_m,
                                          spacing, cfg.min_score)
        in_view = _in_view_check(surface, spacing, drive.K[t], T_world_cam[t], tuple(drive.image_size[t]), near, far)
        tracker.step(t, observations, in_view, passed_node=int(np.floor(surface.frame_s[t] / spacing)))
    lines = tracker.lines(cfg.curvature_noise, cfg.min_length_m, cfg.max_std_m, cfg.max_gap_m)
    labeled = surface.frame_s[-1] + far - surface.frame_s >= cfg.reach_m
    lanes = [frame_labels(surface, lines, spacing, t, drive.T_world_lane[t], drive.K[t], drive.T_lane_cam[t],
                          tuple(drive.image_size[t]), cfg.range_m,
                          None if drive.occluded is None else drive.occluded[t])
             if labeled[t] else [] for t in range(len(drive.stamps))]
    return AutoLabels(lanes, labeled, lines, surface)


def _in_view_check(surface: RoadSurface, spacing: float, K: np.ndarray, T_world_cam: np.ndarray,
                   image_size: tuple[int, int], near: float, far: float):
    """in_view(track) of a frame: the track has nodes at camera depths within the projection range
    that fall into the image, so it should have been detected."""
    T_cam_world = np.linalg.inv(T_world_cam)
    K = torch.from_numpy(K)

    def in_view(track: Track) -> bool:
        nodes, d, _ = track.observed()
        cam = surface.point(nodes * spacing, d) @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
        ahead = (cam[:, 2] >= near) & (cam[:, 2] <= far)
        if ahead.sum() < MIN_OVERLAP_NODES:
            return False
        uv, _ = project(torch.from_numpy(cam[ahead]), K)
        return int(in_image(uv, *image_size).sum()) >= MIN_OVERLAP_NODES

    return in_view

