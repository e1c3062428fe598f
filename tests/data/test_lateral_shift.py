"""Lateral shift: the markings, labels and sky of a frame seen by an ego moved sideways."""

from __future__ import annotations

import numpy as np
import torch

from lanelab.data.lateral_shift import LateralShift, shift_images, shift_targets
from lanelab.geometry import project_lane_points

H, W = 96, 128
K = np.array([[111.0, 0.0, 64.0], [0.0, 111.0, 44.0], [0.0, 0.0, 1.0]])
PITCH = np.radians(2.0)  # looking down
# Camera (x right, y down, z forward) in the lane frame (x right, y forward, z up), 1.5 m up.
T_LANE_CAM = np.array([
    [1.0, 0.0, 0.0, 0.0],
    [0.0, -np.sin(PITCH), np.cos(PITCH), 0.0],
    [0.0, -np.cos(PITCH), -np.sin(PITCH), 1.5],
    [0.0, 0.0, 0.0, 1.0],
])  # fmt: skip


def pixel_of(x: float, y: float, z: float = 0.0) -> np.ndarray:
    uv, _, _ = project_lane_points(torch.tensor([[x, y, z]], dtype=torch.float64), torch.from_numpy(K),
                                   torch.from_numpy(T_LANE_CAM))  # fmt: skip
    return uv[0].numpy()


def blob_at(uv: np.ndarray) -> np.ndarray:
    """A (1, H, W, 3) uint8 image: grey, with a bright Gaussian spot centred on uv (pixel-area convention)."""
    u, v = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    spot = np.exp(-((u - uv[0]) ** 2 + (v - uv[1]) ** 2) / (2 * 1.5**2))
    return np.repeat((60 + 190 * spot).round().astype(np.uint8)[None, ..., None], 3, axis=-1)


def centroid(image: np.ndarray) -> np.ndarray:
    weight = np.clip(image[..., 0].astype(float) - 100, 0, None)
    u, v = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    return np.array([(weight * u).sum(), (weight * v).sum()]) / weight.sum()


def test_a_ground_marking_moves_to_where_the_shifted_point_projects():
    for shift in (0.8, -1.2):
        image = blob_at(pixel_of(1.75, 12.0))
        shifted = shift_images(image, K[None], T_LANE_CAM[None], shift, border=(0.0, 0.0, 0.0))
        np.testing.assert_allclose(centroid(shifted[0]), pixel_of(1.75 - shift, 12.0), atol=0.15)


def test_the_sky_keeps_its_pixels_and_new_ground_pixels_get_the_border():
    image = np.random.default_rng(0).integers(0, 255, (1, H, W, 3), dtype=np.uint8)
    shifted = shift_images(image, K[None], T_LANE_CAM[None], 1.5, border=(7.0, 7.0, 7.0))[0]
    horizon = int(pixel_of(0.0, 1e6)[1])  # the image row of a point far ahead
    np.testing.assert_array_equal(shifted[: horizon - 1], image[0, : horizon - 1])
    # Moving right by 1.5 m: the bottom right corner shows ground the camera never saw.
    assert (shifted[-1, -1] == 7).all() and not (shifted[horizon + 2 :] == image[0, horizon + 2 :]).all()


def test_targets_move_and_lose_what_leaves_the_image():
    y = np.linspace(3.0, 63.0, 31).astype(np.float32)
    targets = {
        "gt_x": np.array([np.full(31, -1.75), np.full(31, 1.75), np.full(31, 5.0)], np.float32),
        "gt_z": np.zeros((3, 31), np.float32),
        "gt_vis": np.ones((3, 31), np.float32),
        "gt_category": np.array([1, 2, 3]),
        "gt_track_id": np.array([10, 11, 12]),
    }
    targets["gt_vis"][0, 20:] = 0.0  # occluded far part stays occluded
    moved = shift_targets(targets, y, K, T_LANE_CAM, (H, W), -2.0)
    np.testing.assert_allclose(moved["gt_x"], targets["gt_x"] + 2.0)
    assert moved["gt_track_id"].tolist() == [10, 11, 12] and moved["gt_category"].tolist() == [1, 2, 3]
    for lane in range(3):
        u, _ = np.array([pixel_of(x, yy) for x, yy in zip(moved["gt_x"][lane], y)]).T
        expected = targets["gt_vis"][lane] * ((u >= 0) & (u < W))
        np.testing.assert_array_equal(moved["gt_vis"][lane], expected)
    assert moved["gt_vis"][2, 0] == 0 and moved["gt_vis"][2, -1] == 1  # x = 7 m is out of view at 3 m only
    # A lane moved wholly out of view is dropped with its category and identity.
    far = shift_targets(targets, y, K, T_LANE_CAM, (H, W), -60.0)
    assert far["gt_track_id"].tolist() == [] and far["gt_x"].shape == (0, 31)


def test_the_augmentation_moves_a_window_alike_and_draws_per_sample():
    """One draw moves every frame's marking, the current lanes by -d and every pose by +d."""
    images = np.concatenate([blob_at(pixel_of(1.75, 12.0))] * 2)
    K2, T2 = np.stack([K, K]), np.stack([T_LANE_CAM, T_LANE_CAM])
    poses = np.stack([np.eye(4), np.eye(4)])
    poses[1, 1, 3] = 2.0  # the current frame 2 m further on
    y = np.linspace(3.0, 63.0, 31).astype(np.float32)
    targets = {"gt_x": np.full((1, 31), 1.75, np.float32), "gt_z": np.zeros((1, 31), np.float32),
               "gt_vis": np.ones((1, 31), np.float32), "gt_category": np.array([2]), "gt_track_id": np.array([4])}  # fmt: skip
    augment = LateralShift(max_shift=1.0, border=(0, 0, 0))
    torch.manual_seed(0)
    shifts = set()
    for _ in range(3):
        moved, moved_poses, moved_targets = augment(images, K2, T2, poses, targets, y)
        shift = float(moved_poses[0, 0, 3])
        shifts.add(round(shift, 6))
        assert 0 < abs(shift) <= 1.0
        np.testing.assert_allclose(moved_poses[:, :3, 3] - poses[:, :3, 3], [[shift, 0, 0]] * 2, atol=1e-12)
        np.testing.assert_allclose(moved_targets["gt_x"], 1.75 - shift, atol=1e-6)
        for frame in moved:
            np.testing.assert_allclose(centroid(frame), pixel_of(1.75 - shift, 12.0), atol=0.15)
    assert len(shifts) == 3
