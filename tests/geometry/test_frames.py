import torch

from lanelab.geometry import (
    T_BASE_LANE,
    T_LANE_BASE,
    base_lane_transform,
    base_link_to_lane,
    compose,
    euler_to_rotation,
    extrinsic_base_to_lane,
    invert,
    lane_base_transform,
    lane_to_base_link,
    make_transform,
    pose_base_to_lane,
    transform_points,
)


def f64(*values):
    return torch.tensor(values, dtype=torch.float64)


def random_pose(seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    angles = torch.rand(3, generator=g, dtype=torch.float64) * 6 - 3
    return make_transform(euler_to_rotation(*angles), torch.randn(3, generator=g, dtype=torch.float64) * 20)


def test_axes_map_as_designed():
    ahead, left, up = f64(10.0, 0.0, 0.0), f64(0.0, 2.0, 0.0), f64(0.0, 0.0, 1.5)
    points = torch.stack([ahead, left, up])
    lane = base_link_to_lane(points)
    assert torch.equal(lane[0], f64(0.0, 10.0, 0.0))  # 10 m ahead is y_L = 10
    assert torch.equal(lane[1], f64(-2.0, 0.0, 0.0))  # 2 m to the left is x_L = -2
    assert torch.equal(lane[2], f64(0.0, 0.0, 1.5))  # up stays up


def test_point_functions_agree_with_transforms():
    p = torch.randn(4, 9, 3, dtype=torch.float64)
    torch.testing.assert_close(base_link_to_lane(p), transform_points(lane_base_transform(), p))
    torch.testing.assert_close(lane_to_base_link(p), transform_points(base_lane_transform(), p))
    assert torch.equal(T_BASE_LANE, base_lane_transform())
    assert torch.equal(T_LANE_BASE, lane_base_transform())


def test_round_trips_are_exact():
    p = torch.randn(100, 3, dtype=torch.float64)
    assert torch.equal(lane_to_base_link(base_link_to_lane(p)), p)
    assert torch.equal(base_link_to_lane(lane_to_base_link(p)), p)
    assert torch.equal(compose(base_lane_transform(), lane_base_transform()), torch.eye(4, dtype=torch.float64))
    assert torch.equal(invert(base_lane_transform()), lane_base_transform())


def test_transform_dtype_and_rigidity():
    T = base_lane_transform(torch.float32)
    assert T.dtype == torch.float32
    R = T[:3, :3]
    assert torch.equal(R @ R.T, torch.eye(3))
    assert torch.linalg.det(R) == 1.0  # a rotation, not a reflection


def test_pose_conversion_is_consistent():
    T_world_base = random_pose(0)
    p_base = torch.randn(20, 3, dtype=torch.float64)
    T_world_lane = pose_base_to_lane(T_world_base)
    torch.testing.assert_close(
        transform_points(T_world_lane, base_link_to_lane(p_base)), transform_points(T_world_base, p_base)
    )
    # translation (the ego position) does not change, only the axes
    assert torch.equal(T_world_lane[:3, 3], T_world_base[:3, 3])


def test_pose_conversion_batched():
    T_world_base = torch.stack([random_pose(i) for i in range(5)])
    T_world_lane = pose_base_to_lane(T_world_base)
    assert T_world_lane.shape == (5, 4, 4)
    for i in range(5):
        torch.testing.assert_close(T_world_lane[i], pose_base_to_lane(T_world_base[i]))


def test_extrinsic_conversion_is_consistent():
    T_base_cam = random_pose(1)
    p_cam = torch.randn(20, 3, dtype=torch.float64)
    T_lane_cam = extrinsic_base_to_lane(T_base_cam)
    torch.testing.assert_close(
        transform_points(T_lane_cam, p_cam), base_link_to_lane(transform_points(T_base_cam, p_cam))
    )


def test_forward_camera_looks_along_lane_y():
    # The usual front camera: optical z along base x, optical x along -base y (right).
    R_base_cam = f64(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0).reshape(3, 3)
    T_lane_cam = extrinsic_base_to_lane(make_transform(R_base_cam, f64(1.5, 0.0, 1.4)))
    # camera z -> lane y (forward), camera x -> lane x (right), camera y -> lane -z (down)
    assert torch.equal(T_lane_cam[:3, :3], f64(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0).reshape(3, 3))
    assert torch.equal(T_lane_cam[:3, 3], f64(0.0, 1.5, 1.4))
