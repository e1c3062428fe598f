"""The ego's camera: its model from the config, and one frame's view of the world through it.

Every projection goes through :mod:`lanelab.geometry` (world -> base_link -> camera optical
frame -> K), so the renderer and the ground truth share one camera model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from data_ingest.synth.config import CameraConfig
from data_ingest.synth.frame import CameraModel
from lanelab.geometry.camera import project
from lanelab.geometry.transforms import compose, euler_to_rotation, invert, make_transform, transform_points

# The optical axes (x right, y down, z forward) in base_link (x forward, y left, z up).
R_BASE_OPTICAL = torch.tensor([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]], dtype=torch.float64)
NEAR_M = 0.1  # polygons are clipped to this camera depth before projection
SUBPIXEL_BITS = 4  # of the fixed-point coordinates OpenCV draws with


def make_camera(cfg: CameraConfig) -> CameraModel:
    """Pinhole K from the horizontal field of view; mounted ahead of base_link, pitched down."""
    focal = cfg.width / 2 / np.tan(np.deg2rad(cfg.hfov_deg) / 2)
    # Pixel (i, j) covers [i, i + 1) x [j, j + 1) (lanelab.geometry.camera), so the centre is (W/2, H/2).
    K = np.array([[focal, 0.0, cfg.width / 2], [0.0, focal, cfg.height / 2], [0.0, 0.0, 1.0]])
    zero = torch.zeros((), dtype=torch.float64)
    pitch = euler_to_rotation(zero, torch.tensor(np.deg2rad(cfg.pitch_deg), dtype=torch.float64), zero)
    T_base_cam = make_transform(pitch @ R_BASE_OPTICAL,
                                torch.tensor([cfg.mount_forward_m, 0.0, cfg.mount_height_m], dtype=torch.float64))
    return CameraModel(K, cfg.width, cfg.height, T_base_cam.numpy(), cfg.frame_id)


@dataclass(frozen=True)
class Polygons:
    """Polygons as seen in one frame, after culling and near-plane clipping.

    uv: (P, 5, 2) pixel vertices (a clipped quad has up to 5; shorter ones repeat their last).
    centre: (P, 3) camera-frame centroid. index: (P,) the input quad each came from.
    """

    uv: np.ndarray
    centre: np.ndarray
    index: np.ndarray


class View:
    """The camera of one frame at ego pose T_world_base (4, 4)."""

    def __init__(self, camera: CameraModel, T_world_base: np.ndarray) -> None:
        self.camera = camera
        self.T_world_base = T_world_base
        self._K = torch.from_numpy(np.asarray(camera.K, float))
        T_world_cam = compose(torch.from_numpy(np.asarray(T_world_base, float)),
                              torch.from_numpy(np.asarray(camera.T_base_cam, float)))
        self._T_cam_world = invert(T_world_cam)
        self.position = T_world_cam[:3, 3].numpy()  # (3,) camera centre in the world

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> camera optical frame (..., 3)."""
        flat = torch.from_numpy(np.ascontiguousarray(points, float).reshape(-1, 3))
        return transform_points(self._T_cam_world, flat).numpy().reshape(np.shape(points))

    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera-frame points (..., 3) -> pixels (..., 2); NaN where not in front of the camera."""
        flat = torch.from_numpy(np.ascontiguousarray(points_cam, float).reshape(-1, 3))
        uv, _ = project(flat, self._K)
        return uv.numpy().reshape(*np.shape(points_cam)[:-1], 2)

    def horizon(self) -> np.ndarray:
        """(2, 2) two pixels on the horizon line: the image of level directions ahead."""
        forward = self._T_cam_world[2, :3].numpy()  # the optical axis in the world
        heading = np.arctan2(forward[1], forward[0]) + np.array([-0.3, 0.3])
        far = self.position + 1e6 * np.stack([np.cos(heading), np.sin(heading), np.zeros(2)], axis=1)
        return self.project(self.to_camera(far))

    def polygons(self, quads: np.ndarray, outward: np.ndarray) -> Polygons:
        """Quads (P, 4, 3) in the world -> the visible ones in pixels.

        outward: (P, 3) world directions the quads face; a quad facing away from the camera is
        dropped (back-face culling of boxes). A zero direction (the road) is never dropped.
        """
        index = np.arange(len(quads))
        facing = np.einsum("pc,pc->p", outward, quads.mean(axis=1) - self.position) <= 0
        quads, index = quads[facing], index[facing]
        clipped, keep = clip_near(self.to_camera(quads), NEAR_M)
        clipped, index = clipped[keep], index[keep]
        return Polygons(self.project(clipped), clipped.mean(axis=1), index)


def cv_points(uv: np.ndarray) -> np.ndarray:
    """Pixels (..., 2) -> int32 fixed-point points for OpenCV drawing with ``shift=SUBPIXEL_BITS``.

    OpenCV puts integer coordinates at pixel centres, lanelab.geometry at pixel corners.
    """
    return np.round((np.clip(uv, -1e7, 1e7) - 0.5) * (1 << SUBPIXEL_BITS)).astype(np.int32)


def clip_near(polygons: np.ndarray, near: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip convex camera-frame polygons (P, K, 3) to depth z >= near (Sutherland-Hodgman, one plane).

    Returns (P, K + 1, 3) polygons, shorter ones padded by repeating their last vertex, and a
    (P,) mask of those with an area left. Points behind the camera are never projected.
    """
    P, K, _ = polygons.shape
    inside = polygons[..., 2] >= near
    following = np.roll(polygons, -1, axis=1)
    crosses = inside != np.roll(inside, -1, axis=1)
    dz = following[..., 2] - polygons[..., 2]
    t = np.where(crosses, (near - polygons[..., 2]) / np.where(crosses, dz, 1.0), 0.0)
    crossing = polygons + t[..., None] * (following - polygons)
    # Walking the edges: each vertex if inside, then the crossing point if the edge crosses.
    candidates = np.stack([polygons, crossing], axis=2).reshape(P, 2 * K, 3)
    kept = np.stack([inside, crosses], axis=2).reshape(P, 2 * K)
    count = kept.sum(axis=1)
    order = np.argsort(~kept, axis=1, kind="stable")[:, : K + 1]
    slots = np.minimum(np.arange(K + 1), np.maximum(count, 1)[:, None] - 1)
    picked = np.take_along_axis(order, slots, axis=1)
    return np.take_along_axis(candidates, picked[..., None], axis=1), count >= 3
