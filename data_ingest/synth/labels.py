"""Ground truth of a frame: 3D lanes with visibility, noisy 2D detections, an occluder mask, scenario tags.

Lanes are sampled on the road (every metre near the ego, every 2 m farther, at fixed arc
lengths so consecutive frames sample the same road points), expressed in the lane frame of
DESIGN.md and projected with :func:`lanelab.geometry.camera.project_lane_points`. A point is
visible (1) unless it is outside the image, behind a box (a vehicle, a barrier, a building)
or behind a crest; the latter two are worked out independently of the renderer: boxes are
filled into a depth buffer, and the line of sight is tested against the road's surface. The
occluder mask is where that buffer holds a box: what a segmentation network would mark as
vehicles and roadside objects (the auto-labeler's occlusion input).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from data_ingest.synth.boxes import Boxes
from data_ingest.synth.camera import SUBPIXEL_BITS, View, cv_points
from data_ingest.synth.frame import CameraModel, Lane2D
from data_ingest.synth.road import Road
from lanelab.geometry.camera import in_image, project_lane_points
from lanelab.geometry.frames import extrinsic_base_to_lane, pose_base_to_lane
from lanelab.geometry.transforms import invert, transform_points
from lanelab.lanes import Lane

NEAR_STEP_M, FAR_STEP_M, FAR_FROM_M = 1.0, 2.0, 50.0  # label point spacing along the road
ARC_MARGIN = 1.6  # arc length sampled per metre of range: lanes curving away need more
LINE_OF_SIGHT_SAMPLES = 32
CREST_TOLERANCE_M = 0.02
DETECTION_RANGE_M = 50.0
MIN_DETECTION_POINTS = 4
# Tags: curve radii over the next 100 m; how far the road within 150 m may leave the ego's plane and
# stay "flat"; share of the lane points in view within 50 m hidden by boxes that is "heavy" occlusion.
STRAIGHT_MIN_RADIUS_M, CURVE_MIN_RADIUS_M, CURVATURE_LOOKAHEAD_M = 1000.0, 300.0, 100.0
FLAT_MAX_DEVIATION_M, SLOPE_LOOKAHEAD_M = 1.0, 150.0
HEAVY_OCCLUSION, OCCLUSION_RANGE_M = 0.2, 50.0
# Detector quality: (probability of missing a lane, pixel noise) by condition.
DETECTOR_MISS = {"sun": 0.05, "rain": 0.15, "fog": 0.2, "snow": 0.25}
DETECTOR_NOISE_PX = {"sun": 1.0, "rain": 1.8, "fog": 1.5, "snow": 2.0}
NIGHT_MISS, FALSE_FRAGMENTS_PER_FRAME = 0.1, 0.3


@dataclass(frozen=True)
class FrameTruth:
    lanes: list[Lane]
    lanes2d: list[Lane2D]
    tags: dict[str, str]
    occluders: np.ndarray  # (H, W) bool: a box covers the pixel


@dataclass(frozen=True)
class _Points:
    """Every label point of a frame. line: (N,) index into the road's lines; lane: (N, 3) lane
    frame; uv: (N, 2) pixels; visible: (N,) bool."""

    line: np.ndarray
    lane: np.ndarray
    uv: np.ndarray
    visible: np.ndarray


class Labeler:
    """Labels frames of one drive; ``seed`` (ints) seeds the detector noise per frame;
    detector_noise: "row" (pixel noise across the image row only) or "isotropic" (in both axes)."""

    def __init__(self, road: Road, camera: CameraModel, max_range: float, scenario: dict[str, str],
                 seed: tuple[int, ...], detector_noise: str) -> None:
        self.road, self.camera, self.max_range = road, camera, max_range
        self.scenario = scenario
        self.seed = seed
        # A row-anchor 2D detector (CLRNet, LaneATT) reports a lane's x at fixed image rows: its error is across the row.
        self._noise_axes = np.array([1.0, 0.0] if detector_noise == "row" else [1.0, 1.0])
        self._K = torch.from_numpy(np.asarray(camera.K, float))
        self._T_lane_cam = extrinsic_base_to_lane(torch.from_numpy(np.asarray(camera.T_base_cam, float)))

    def label(self, frame_index: int, view: View, ego_s: float, ego_d: float, occluders: Boxes) -> FrameTruth:
        """Ground truth of frame ``frame_index`` seen by ``view``, base_link at road coordinates (ego_s, ego_d)."""
        buffer = self._box_depths(view, occluders)
        points, in_view, occluded = self._points(view, ego_s, ego_d, buffer)
        lanes = []
        for k, line in enumerate(self.road.cross_section.lines):
            mine = points.line == k
            if mine.sum() >= 2:
                lanes.append(Lane(points.lane[mine], points.visible[mine].astype(np.float32), line.category,
                                  track_id=line.track_id))
        rng = np.random.default_rng([*self.seed, frame_index])
        near = points.lane[:, 1] <= OCCLUSION_RANGE_M
        return FrameTruth(lanes, self._detections(points, rng), self._tags(ego_s, in_view & near, occluded & near),
                          np.isfinite(buffer))

    def _points(self, view: View, ego_s: float, ego_d: float, box_depths: np.ndarray):
        """The frame's label points, and (N,) masks of those in view (in the image, not behind a crest)
        and of those among them hidden by boxes."""
        line, s, d = self._samples(ego_s)
        world = self.road.surface(s, d)
        T_lane_world = invert(pose_base_to_lane(torch.from_numpy(np.asarray(view.T_world_base, float))))
        lane = transform_points(T_lane_world, torch.from_numpy(world)).numpy()
        keep = _ahead_and_ascending(line, lane[:, 1], self.max_range)
        line, s, d, world, lane = line[keep], s[keep], d[keep], world[keep], lane[keep]
        uv, depth, in_front = project_lane_points(torch.from_numpy(lane), self._K, self._T_lane_cam)
        inside = (in_front & in_image(uv, self.camera.width, self.camera.height)).numpy()
        uv, depth = uv.numpy(), depth.numpy()
        cam_s = ego_s + self.camera.T_base_cam[0, 3]
        in_view = inside & ~self._behind_crest(s, d, world, view.position, cam_s, ego_d)
        occluded = in_view & _behind_boxes(box_depths, uv, depth, in_view)
        points = _Points(line, lane, uv, in_view & ~occluded)
        return points, in_view, occluded

    def _samples(self, ego_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Road coordinates of the candidate points: (N,) line index, s, d; fixed arc lengths along the road."""
        end = min(ego_s + ARC_MARGIN * self.max_range, self.road.length)
        near = np.arange(np.ceil(ego_s / NEAR_STEP_M), np.floor(ego_s + FAR_FROM_M) + 1) * NEAR_STEP_M
        far = np.arange(np.floor((ego_s + FAR_FROM_M) / FAR_STEP_M) + 1, np.floor(end / FAR_STEP_M) + 1) * FAR_STEP_M
        grid = np.concatenate([near, far])
        xs = self.road.cross_section
        parts = [(k, grid[(grid >= line.start) & (grid <= line.end)]) for k, line in enumerate(xs.lines)]
        line = np.concatenate([np.full(len(s), k) for k, s in parts])
        s = np.concatenate([s for _, s in parts])
        d = np.concatenate([xs.line_offset(xs.lines[k], s) for k, s in parts])
        return line, s, d

    def _behind_crest(self, s: np.ndarray, d: np.ndarray, world: np.ndarray, camera: np.ndarray,
                      cam_s: float, cam_d: float) -> np.ndarray:
        """(N,) bool: the line of sight from the camera to the point dips below the road surface.

        The sight line's ground track is taken as the straight line from the camera's road
        coordinates (s, d) to the point's: what the surface height depends on (elevation along s,
        bank across d), without inverting the plan view.
        """
        f = np.linspace(0.0, 1.0, LINE_OF_SIGHT_SAMPLES + 2)[1:-1, None]  # (F, 1), ends excluded
        ray_z = camera[2] + f * (world[:, 2] - camera[2])
        ground = self.road.height(cam_s + f * (s - cam_s), cam_d + f * (d - cam_d))
        return (ray_z < ground - CREST_TOLERANCE_M).any(axis=0)

    def _box_depths(self, view: View, boxes: Boxes) -> np.ndarray:
        """(H, W) float32 depth buffer of the boxes: per pixel the depth of the nearest box it shows, inf for none."""
        buffer = np.full((self.camera.height, self.camera.width), np.inf, np.float32)
        if not len(boxes):
            return buffer
        quads, outward, box, _ = boxes.face_quads(self.road)
        seen = view.polygons(quads, outward)
        # A box's nearest corner stands for all of it: points under or behind it are farther.
        nearest = view.to_camera(boxes.corners(self.road))[..., 2].min(axis=1)[box[seen.index]]
        order = np.argsort(-nearest)
        for polygon, z in zip(cv_points(seen.uv[order]), nearest[order].tolist()):
            cv2.fillConvexPoly(buffer, polygon, z, cv2.LINE_8, SUBPIXEL_BITS)
        return buffer

    def _detections(self, points: _Points, rng: np.random.Generator) -> list[Lane2D]:
        """What a decent 2D lane detector would find: near visible runs, jittered (a smooth drift and
        per-point noise along the detector's noise axes), some missed, a few false."""
        weather, night = self.scenario["weather"], self.scenario["daytime"] == "night"
        miss = DETECTOR_MISS[weather] + (NIGHT_MISS if night else 0.0)
        noise = DETECTOR_NOISE_PX[weather] * (1.5 if night else 1.0)
        near = points.visible & (points.lane[:, 1] <= DETECTION_RANGE_M)
        detections = []
        for k, line in enumerate(self.road.cross_section.lines):
            for run in _runs(np.nonzero(near & (points.line == k))[0]):
                if len(run) < MIN_DETECTION_POINTS or rng.random() < miss:
                    continue
                run = run[: max(MIN_DETECTION_POINTS, int(len(run) * rng.uniform(0.6, 1.0)))]
                t = np.linspace(0.0, 1.0, len(run))[:, None]
                drift = rng.normal(0.0, noise, 2) + rng.normal(0.0, 2 * noise, 2) * t  # a smooth bias
                uv = points.uv[run] + (drift + rng.normal(0.0, noise, (len(run), 2))) * self._noise_axes
                score = float(np.clip(rng.normal(0.9 - miss, 0.05), 0.3, 0.99))
                detections.append(Lane2D(uv.astype(np.float32), score, line.category))
        for _ in range(rng.poisson(FALSE_FRAGMENTS_PER_FRAME + miss)):
            detections.append(self._false_fragment(rng))
        return detections

    def _false_fragment(self, rng: np.random.Generator) -> Lane2D:
        """A short streak in the lower half of the image, leaning towards the image centre."""
        W, H = self.camera.width, self.camera.height
        start = np.array([rng.uniform(0, W), rng.uniform(0.6 * H, H)])
        direction = np.array([W / 2, H / 2]) - start
        step = direction / np.linalg.norm(direction) * rng.uniform(6.0, 12.0)
        uv = start + np.arange(rng.integers(4, 9))[:, None] * step + rng.normal(0.0, 1.0, (1, 2))
        return Lane2D(uv.astype(np.float32), float(rng.uniform(0.2, 0.6)), int(rng.choice([1, 2])))

    def _tags(self, ego_s: float, in_view: np.ndarray, occluded: np.ndarray) -> dict[str, str]:
        """Scenario tags; in_view, occluded: (N,) masks of the near lane points."""
        ahead = ego_s + np.linspace(0.0, CURVATURE_LOOKAHEAD_M, 101)
        radius = 1.0 / max(np.abs(self.road.curvature(ahead)).max(), 1e-9)
        curvature = "straight" if radius > STRAIGHT_MIN_RADIUS_M else "curve" if radius > CURVE_MIN_RADIUS_M \
            else "strong_curve"
        # Height of the road ahead above the plane the ego stands on: crests and sags, not steady grades.
        ahead = ego_s + np.linspace(0.0, SLOPE_LOOKAHEAD_M, 151)
        rise = self.road.height(ahead, 0.0) - self.road.height(ego_s, 0.0) - self.road.grade(ego_s) * (ahead - ego_s)
        ends = [e for line in self.road.cross_section.lines for e in (line.start, line.end)]
        merging = any(ego_s <= e <= ego_s + self.max_range for e in ends)
        share = occluded.sum() / max(in_view.sum(), 1)
        occlusion = "none" if not occluded.any() else "heavy" if share >= HEAVY_OCCLUSION else "some"
        return {
            "environment": self.scenario["environment"],
            "daytime": self.scenario["daytime"],
            "weather": self.scenario["weather"],
            "curvature": curvature,
            "slope": "up_down" if np.abs(rise).max() > FLAT_MAX_DEVIATION_M else "flat",
            "merge_split": "yes" if merging else "no",
            "occlusion": occlusion,
        }


def _ahead_and_ascending(line: np.ndarray, y: np.ndarray, max_range: float) -> np.ndarray:
    """(N,) bool: per line, the points from y >= 0 on while y keeps growing and stays within range.

    A lane is a function of y (DESIGN.md); a curve turning back towards the ego ends it.
    """
    keep = np.zeros(len(y), bool)
    for k in np.unique(line):
        index = np.nonzero(line == k)[0]
        yk = y[index]
        ok = (yk >= 0) & (yk <= max_range)
        first = np.argmax(ok) if ok.any() else len(yk)
        rising = np.concatenate([[True], np.diff(yk[first:]) > 0]) & ok[first:]
        stop = first + (np.argmin(rising) if not rising.all() else len(rising))
        keep[index[first:stop]] = True
    return keep


def _behind_boxes(box_depths: np.ndarray, uv: np.ndarray, depth: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """(N,) bool: the point's pixel shows a box nearer than the point; box_depths (H, W) the boxes' depth buffer."""
    hidden = np.zeros(len(uv), bool)
    if not candidates.any() or not np.isfinite(box_depths).any():
        return hidden
    # Silhouette edges are uncertain by a pixel (thin gaps between a line and a wall behind it):
    # shrink them by one, so only points well inside count as hidden.
    buffer = cv2.dilate(box_depths, np.ones((3, 3), np.uint8))
    col, row = np.floor(uv[candidates]).astype(np.int64).T
    hidden[candidates] = buffer[row, col] < depth[candidates]
    return hidden


def _runs(index: np.ndarray) -> list[np.ndarray]:
    """Split sorted indices (N,) into runs of consecutive ones."""
    return np.split(index, np.nonzero(np.diff(index) != 1)[0] + 1) if len(index) else []
