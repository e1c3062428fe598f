import math

import pytest
import torch

from lanelab.geometry import (
    backproject,
    backproject_to_lane,
    euler_to_rotation,
    in_image,
    intersect_ground,
    make_transform,
    pixel_rays,
    project,
    project_lane_points,
    transform_points,
)

WIDTH, HEIGHT = 640, 480


def intrinsics(dtype=torch.float64) -> torch.Tensor:
    return torch.tensor([[1000.0, 0.0, 320.0], [0.0, 1000.0, 240.0], [0.0, 0.0, 1.0]], dtype=dtype)


def front_camera(height: float = 1.5, pitch_down: float = 0.05, dtype=torch.float64) -> torch.Tensor:
    """T_lane_cam of a forward camera `height` m above the ground, pitched down."""
    # optical x -> lane x (right), optical y -> lane -z (down), optical z -> lane y (forward)
    level = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=dtype)
    zero = torch.tensor(0.0, dtype=dtype)
    pitch = euler_to_rotation(torch.tensor(-pitch_down, dtype=dtype), zero, zero)  # about lane x
    return make_transform(pitch @ level, torch.tensor([0.0, 0.0, height], dtype=dtype))


def test_project_known_value():
    uv, in_front = project(torch.tensor([[1.0, 0.5, 10.0]], dtype=torch.float64), intrinsics())
    torch.testing.assert_close(uv, torch.tensor([[420.0, 290.0]], dtype=torch.float64))
    assert in_front.tolist() == [True]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_points_behind_the_camera_are_flagged(dtype):
    points = torch.tensor([[1.0, 0.5, 10.0], [1.0, 0.5, -10.0], [1.0, 0.5, 0.0], [1.0, 0.5, 1e-4]], dtype=dtype)
    uv, in_front = project(points, intrinsics(dtype))
    assert uv.dtype == dtype
    assert in_front.tolist() == [True, False, False, False]
    assert torch.isfinite(uv[0]).all() and torch.isnan(uv[1:]).all()
    assert in_image(uv, WIDTH, HEIGHT).tolist() == [True, False, False, False]


def test_project_has_no_nan_gradient_for_valid_points():
    points = torch.tensor([[1.0, 0.5, 10.0], [1.0, 0.5, 0.0]], dtype=torch.float64, requires_grad=True)
    uv, in_front = project(points, intrinsics())
    uv[in_front].sum().backward()
    assert torch.isfinite(points.grad).all()


def test_in_image_edges():
    uv = torch.tensor(
        [[0.0, 0.0], [639.999, 479.999], [640.0, 10.0], [10.0, 480.0], [-1e-9, 10.0], [10.0, -0.5], [math.nan, 10.0]],
        dtype=torch.float64,
    )
    assert in_image(uv, WIDTH, HEIGHT).tolist() == [True, True, False, False, False, False, False]


def test_pixel_rays_have_unit_depth_and_reproject():
    uv = torch.tensor([[0.0, 0.0], [320.0, 240.0], [600.5, 13.25]], dtype=torch.float64)
    rays = pixel_rays(uv, intrinsics())
    torch.testing.assert_close(rays[:, 2], torch.ones(3, dtype=torch.float64))
    torch.testing.assert_close(rays[1], torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    torch.testing.assert_close(project(rays, intrinsics())[0], uv)


def test_backproject_round_trip_batched_with_skew():
    K = intrinsics().expand(3, 3, 3).clone()
    K[:, 0, 1] = torch.tensor([0.0, 2.0, -5.0], dtype=torch.float64)  # skew
    points = torch.randn(3, 50, 3, dtype=torch.float64)
    points[..., 2] = points[..., 2].abs() + 1.0
    uv, in_front = project(points, K)
    assert in_front.all()
    torch.testing.assert_close(backproject(uv, points[..., 2], K), points)


def test_lane_projection_round_trip():
    T_lane_cam = front_camera()
    points = torch.stack(
        [torch.linspace(-5, 5, 30), torch.linspace(5, 80, 30), torch.linspace(-0.5, 1.0, 30)], -1
    ).double()
    uv, depth, in_front = project_lane_points(points, intrinsics(), T_lane_cam)
    assert in_front.all()
    torch.testing.assert_close(backproject_to_lane(uv, depth, intrinsics(), T_lane_cam), points)
    # depth is the distance along the optical axis
    torch.testing.assert_close(depth, transform_points(torch.linalg.inv(T_lane_cam), points)[:, 2])


def test_lane_points_behind_the_ego_are_flagged():
    uv, depth, in_front = project_lane_points(
        torch.tensor([[0.0, 20.0, 0.0], [0.0, -20.0, 0.0]], dtype=torch.float64), intrinsics(), front_camera()
    )
    assert in_front.tolist() == [True, False]
    assert depth[1] < 0 and torch.isnan(uv[1]).all()


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_intersect_ground_round_trip(dtype):
    T_lane_cam = front_camera(height=1.5, pitch_down=0.05, dtype=dtype)
    x, y = torch.meshgrid(torch.linspace(-6, 6, 7), torch.linspace(4, 100, 9), indexing="ij")
    ground = torch.stack([x, y, torch.zeros_like(x)], -1).reshape(-1, 3).to(dtype)
    uv, _, in_front = project_lane_points(ground, intrinsics(dtype), T_lane_cam)
    assert in_front.all()
    points, valid = intersect_ground(uv, intrinsics(dtype), T_lane_cam)
    assert valid.all() and points.dtype == dtype
    tolerance = 1e-3 if dtype == torch.float32 else 1e-9
    torch.testing.assert_close(points, ground, atol=tolerance, rtol=0)


def test_intersect_ground_height_and_invalid_rays():
    T_lane_cam = front_camera(height=1.5, pitch_down=0.05)
    # a pixel far above the horizon looks at the sky; the principal point hits the ground
    uv = torch.tensor([[320.0, 0.0], [320.0, 240.0]], dtype=torch.float64)
    points, valid = intersect_ground(uv, intrinsics(), T_lane_cam)
    assert valid.tolist() == [False, True]
    assert torch.isnan(points[0]).all()
    torch.testing.assert_close(points[1], torch.tensor([0.0, 1.5 / math.tan(0.05), 0.0], dtype=torch.float64))
    # a raised plane per point
    raised = torch.tensor([0.5], dtype=torch.float64)
    points, valid = intersect_ground(uv[1:], intrinsics(), T_lane_cam, ground_z=raised)
    assert valid.all()
    torch.testing.assert_close(points[0], torch.tensor([0.0, 1.0 / math.tan(0.05), 0.5], dtype=torch.float64))
