"""Lateral shift of a frame: what the camera sees when the ego moves sideways by d metres.

Moving the ego (its lane frame, camera and all) by d along the lane frame's x (right) moves every
lane by -d in that frame. For points on the ground plane z = 0 the new image is the old one under
a homography: with G = K [r1 r2 t] the map from ground points (x, y, 1) to pixels (r1, r2 and t
the columns of T_cam_lane for x, y and the translation), a ground point seen at pixel p is seen at
G S G^-1 p, S the ground translation by -d. Lane markings therefore move exactly (up to the road's
grade); raised things (vehicles, trees) are sheared. Above the horizon the homography shears
the sky ever more with height, so the pixels there keep their old values. Pixels that come from
outside the old image are filled with ``border``, and lane samples that leave the new image are no
longer visible, as the ground truth marks samples outside the camera's view.

benchmarks/shift_probe.py uses it to ask whether a trained detector reads where a lane lies
across the road. :class:`LateralShift` is the same as a training augmentation: synthetic egos
(as real ones) drive centred in their lane, so without it every training lane lies where lanes
usually lie, and a detector (or its lateral-offset map, models.sparselanestp.lateral_offset) can fit the
training roads by learning that template instead of reading the image. (Alone, with the query
decoders, it made them read positions less precisely than the blind prior places them:
benchmarks/RESULTS.md, tenth round; with the lateral-offset map, issue "Decoders that read the
road", it is what makes the map read.)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from lanelab.geometry import project_lane_points

# cv2 puts pixel centres at integers; lanelab's pixel-area convention at half-integers.
_TO_CV = np.array([[1.0, 0.0, -0.5], [0.0, 1.0, -0.5], [0.0, 0.0, 1.0]])


def ground_to_pixels(K: np.ndarray, T_lane_cam: np.ndarray) -> np.ndarray:
    """G (3, 3): lane-frame ground points (x, y, 1) at z = 0 -> homogeneous pixels."""
    T_cam_lane = np.linalg.inv(T_lane_cam)
    return K @ T_cam_lane[:3][:, [0, 1, 3]]


def _shift_homography(G: np.ndarray, G_inv: np.ndarray, shift: float) -> np.ndarray:
    """(3, 3) pixel map (cv2's convention) of the image seen after moving the ego by ``shift`` m
    along x, from the ground-to-pixel map G (:func:`ground_to_pixels`) and its inverse."""
    S = np.array([[1.0, 0.0, -shift], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return _TO_CV @ G @ S @ G_inv @ np.linalg.inv(_TO_CV)


def shift_images(images: np.ndarray, K: np.ndarray, T_lane_cam: np.ndarray, shift: float,
                 border: tuple[float, float, float]) -> np.ndarray:  # fmt: skip
    """images (F, H, W, 3) (uint8, or float32 normalised) with their K (F, 3, 3) and T_lane_cam
    (F, 4, 4) -> the images seen after moving the ego by ``shift`` metres to the right; new pixels
    are ``border``."""
    height, width = images.shape[1:3]
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    centres = np.stack([u, v, np.ones_like(u)], -1)  # (H, W, 3) pixel centres
    shifted = np.empty_like(images)
    for f, (image, k, t) in enumerate(zip(images, K, T_lane_cam)):
        G = ground_to_pixels(k, t)
        G_inv = np.linalg.inv(G)
        homography = _shift_homography(G, G_inv, shift)
        warped = cv2.warpPerspective(image, homography, (width, height), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=border)  # fmt: skip
        ground = (centres @ G_inv[2]) > 0  # (H, W): below the horizon
        shifted[f] = np.where(ground[..., None], warped, image)
    return shifted


def shift_targets(targets: dict[str, np.ndarray], y: np.ndarray, K: np.ndarray, T_lane_cam: np.ndarray,
                  image_size: tuple[int, int], shift: float) -> dict[str, np.ndarray]:  # fmt: skip
    """Lane targets (:class:`~lanelab.data.targets.LaneTargets` output, at the grid y (S,)) after
    moving the ego by ``shift`` metres: x moves by -shift, samples that leave the image of the
    current frame's camera (K (3, 3), T_lane_cam (4, 4), image_size (H, W)) become invisible, and
    lanes left with fewer than two visible samples are dropped, as LaneTargets drops them."""
    x = targets["gt_x"] - np.float32(shift)
    points = np.stack([x, np.broadcast_to(y, x.shape), targets["gt_z"]], -1).astype(np.float64)
    camera = (torch.from_numpy(np.asarray(a, np.float64)) for a in (K, T_lane_cam))
    uv, _, in_front = project_lane_points(torch.from_numpy(points), *camera)
    u, v = uv.nan_to_num(-1.0).unbind(-1)
    height, width = image_size
    inside = (in_front & (u >= 0) & (u < width) & (v >= 0) & (v < height)).numpy()
    visible = (targets["gt_vis"] * inside).astype(np.float32)
    keep = visible.sum(-1) >= 2
    shifted = {**targets, "gt_x": x.astype(np.float32), "gt_vis": visible}
    return {name: value[keep] for name, value in shifted.items()}


def shift_poses(T_world_lane: np.ndarray, shift: float) -> np.ndarray:
    """Ego poses (F, 4, 4) of an ego moved ``shift`` metres to the right in each of its frames."""
    moved = np.eye(4)
    moved[0, 3] = shift
    return T_world_lane @ moved


@dataclass(frozen=True)
class LateralShift:
    """Training augmentation: each sample is seen from an ego moved sideways by d, uniform in
    [-max_shift, max_shift] metres, drawn once per sample from torch's generator (seeded per
    loader worker, as :class:`~lanelab.data.augment.PhotometricAugment`). All frames of a window
    move alike (images, poses), so the window stays a consistent drive; the current frame's
    lanes move by -d. New pixels get ``border`` (uint8 RGB; the normalisation's mean by default
    in the data config)."""

    max_shift: float
    border: tuple[int, int, int]

    def __call__(
        self,
        images: np.ndarray,
        K: np.ndarray,
        T_lane_cam: np.ndarray,
        T_world_lane: np.ndarray,
        targets: dict[str, np.ndarray],
        y: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """images (F, H, W, 3) uint8 with K (F, 3, 3), T_lane_cam, T_world_lane (F, 4, 4); targets
        of the current (last) frame at the grid y (S,). Returns the images, poses and targets
        after the shift."""
        shift = float((torch.rand(()) * 2 - 1) * self.max_shift)
        if shift == 0.0:
            return images, T_world_lane, targets
        images = shift_images(images, K, T_lane_cam, shift, border=tuple(float(c) for c in self.border))
        targets = shift_targets(targets, y, K[-1], T_lane_cam[-1], images.shape[1:3], shift)
        return images, shift_poses(T_world_lane, shift), targets
