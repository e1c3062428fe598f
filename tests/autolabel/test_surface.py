"""The road surface of the ego trajectory: rays meet it where geometry says."""

from __future__ import annotations

import numpy as np
import torch

from data_ingest.autolabel.surface import RoadSurface
from lanelab.geometry.transforms import euler_to_rotation


def poses(rotations: list[np.ndarray], positions: list[np.ndarray]) -> np.ndarray:
    T = np.tile(np.eye(4), (len(positions), 1, 1))
    for k, (R, p) in enumerate(zip(rotations, positions)):
        T[k, :3, :3], T[k, :3, 3] = R, p
    return T


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return euler_to_rotation(*(torch.tensor(a, dtype=torch.float64) for a in (roll, pitch, yaw))).numpy()


def test_a_ray_meets_a_tilted_plane_segment_where_the_plane_equation_says():
    R = rotation(0.04, -0.07, 0.6)  # banked, climbing, heading north-east
    start = np.array([10.0, -3.0, 2.0])
    surface = RoadSurface(poses([R, R], [start, start + 12.0 * R[:, 1]]))  # lane-frame y is forward
    origin = start + 1.6 * R[:, 2] - 1.0 * R[:, 1]  # a camera 1.6 m above the road
    rng = np.random.default_rng(0)
    # Rays down to points of the segment (forward 1 .. 11 m, lateral -6 .. 6 m), off the plane by noise.
    targets = start + rng.uniform(1, 11, (50, 1)) * R[:, 1] + rng.uniform(-6, 6, (50, 1)) * R[:, 0]
    rays = targets - origin + rng.normal(0, 0.05, (50, 3))
    points, s, d, valid = surface.intersect(origin, rays)
    normal = R[:, 2]
    t = ((start - origin) @ normal) / (rays @ normal)  # the plane through start with that normal
    assert valid.all()
    np.testing.assert_allclose(points, origin + t[:, None] * rays, atol=1e-6)
    np.testing.assert_allclose((points - start) @ R[:, 1], s, atol=1e-6)  # s: along the segment
    np.testing.assert_allclose((points - start) @ R[:, 0], d, atol=1e-6)  # d: to the right
    np.testing.assert_allclose(surface.point(s, d), points, atol=1e-6)


def test_rays_that_miss_the_road_ahead_are_invalid():
    R = np.eye(3)
    surface = RoadSurface(poses([R, R], [np.zeros(3), np.array([0.0, 10.0, 0.0])]))
    origin = np.array([0.0, 0.0, 1.5])
    points, _, _, valid = surface.intersect(origin, np.array([[0.0, 1.0, 0.1], [0.0, 1.0, -0.1]]))
    assert valid.tolist() == [False, True]  # the first points to the sky
    assert np.isnan(points[0]).all()
    np.testing.assert_allclose(points[1], [0.0, 15.0, 0.0], atol=1e-9)  # on the last pose's plane, beyond it


def test_on_a_curve_hits_lie_on_the_ray_and_on_the_blend_of_the_cross_sections():
    yaws = np.linspace(0.0, 0.4, 9)  # a 100 m radius curve, 5 m between poses, banked into it
    positions = [np.array([100 * np.sin(a), 100 * (1 - np.cos(a)), 0.02 * k]) for k, a in enumerate(yaws)]
    T = poses([rotation(-0.03, 0.0, a) for a in yaws], positions)
    from lanelab.geometry.frames import pose_base_to_lane  # the poses above are base_link's
    T = pose_base_to_lane(torch.from_numpy(T)).numpy()
    surface = RoadSurface(T)
    origin = T[0, :3, 3] + np.array([0.0, 0.0, 1.5])
    rng = np.random.default_rng(1)
    rays = np.stack([np.cos(rng.uniform(-0.2, 0.5, 40)), np.sin(rng.uniform(-0.2, 0.5, 40)),
                     -rng.uniform(0.04, 0.3, 40)], axis=1)
    points, s, d, valid = surface.intersect(origin, rays)
    assert valid.all()
    along = (points - origin) @ rays.T
    np.testing.assert_allclose(np.cross(points - origin, rays), 0.0, atol=1e-6)  # on the ray
    assert (np.diag(along) > 0).all()
    np.testing.assert_allclose(surface.point(s, d), points, atol=1e-6)  # on the surface
