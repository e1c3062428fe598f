import math

import pytest
import torch

from lanelab.geometry import (
    compose,
    euler_to_rotation,
    interpolate_pose,
    invert,
    make_transform,
    quaternion_to_rotation,
    rotation_to_quaternion,
    slerp,
    transform_points,
)


def random_poses(*batch: int, seed: int = 0, dtype=torch.float64) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    angles = (torch.rand(3, *batch, generator=g, dtype=dtype) * 2 - 1) * math.pi
    t = torch.randn(*batch, 3, generator=g, dtype=dtype) * 10
    return make_transform(euler_to_rotation(*angles), t)


def axis_angle(axis, angle: float) -> torch.Tensor:
    """Rotation matrix by Rodrigues' formula, written independently of the module."""
    k = torch.tensor(axis, dtype=torch.float64)
    k = k / k.norm()
    K = torch.tensor([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def eye(*batch: int) -> torch.Tensor:
    return torch.eye(4, dtype=torch.float64).expand(*batch, 4, 4)


def test_make_transform_layout_and_broadcast():
    R = euler_to_rotation(*torch.rand(3, 5, dtype=torch.float64))
    T = make_transform(R, torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64))
    assert T.shape == (5, 4, 4)
    assert torch.equal(T[:, :3, :3], R)
    assert torch.equal(T[:, :3, 3], torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64).expand(5, 3))
    assert torch.equal(T[:, 3], torch.tensor([0.0, 0.0, 0.0, 1.0], dtype=torch.float64).expand(5, 4))


def test_invert_compose_is_identity():
    T = random_poses(7)
    torch.testing.assert_close(compose(invert(T), T), eye(7))
    torch.testing.assert_close(compose(T, invert(T)), eye(7))
    torch.testing.assert_close(invert(T), torch.linalg.inv(T))


def test_compose_is_left_to_right_and_broadcasts():
    A, B, C = random_poses(seed=1), random_poses(4, seed=2), random_poses(3, 1, seed=3)
    ABC = compose(A, B, C)
    assert ABC.shape == (3, 4, 4, 4)
    torch.testing.assert_close(ABC, A @ B @ C)
    p = torch.randn(5, 3, dtype=torch.float64)
    # T_a_c = T_a_b T_b_c: applying the product equals applying C first, then B, then A.
    expected = transform_points(A, transform_points(B, transform_points(C, p)))
    torch.testing.assert_close(transform_points(ABC, p), expected)


def test_transform_points_matches_homogeneous_product():
    T = random_poses(2, 3)
    p = torch.randn(2, 3, 6, 3, dtype=torch.float64)
    homogeneous = torch.cat([p, torch.ones_like(p[..., :1])], -1)
    expected = (homogeneous @ T.transpose(-1, -2))[..., :3]
    torch.testing.assert_close(transform_points(T, p), expected)


def test_euler_ros_convention():
    quarter_turn = euler_to_rotation(*torch.tensor([0.0, 0.0, math.pi / 2], dtype=torch.float64))
    torch.testing.assert_close(quarter_turn, axis_angle([0, 0, 1], math.pi / 2))
    roll, pitch, yaw = 0.3, -0.4, 1.1
    expected = axis_angle([0, 0, 1], yaw) @ axis_angle([0, 1, 0], pitch) @ axis_angle([1, 0, 0], roll)
    got = euler_to_rotation(*torch.tensor([roll, pitch, yaw], dtype=torch.float64))
    torch.testing.assert_close(got, expected)


def test_quaternion_known_value():
    # 90 degrees about z: (0, 0, sin 45°, cos 45°)
    q = rotation_to_quaternion(axis_angle([0, 0, 1], math.pi / 2))
    s = math.sqrt(0.5)
    torch.testing.assert_close(q, torch.tensor([0.0, 0.0, s, s], dtype=torch.float64))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_quaternion_round_trip_random(dtype):
    R = random_poses(1000, seed=4, dtype=dtype)[:, :3, :3]
    q = rotation_to_quaternion(R)
    assert q.dtype == dtype and q.shape == (1000, 4)
    assert (q[:, 3] >= 0).all()
    torch.testing.assert_close(q.norm(dim=-1), torch.ones(1000, dtype=dtype))
    torch.testing.assert_close(quaternion_to_rotation(q), R, atol=1e-5 if dtype == torch.float32 else 1e-12, rtol=0)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -2, 3]])
@pytest.mark.parametrize("angle", [math.pi, math.pi - 1e-7, math.pi - 1e-3, 1e-9])
def test_quaternion_round_trip_near_180_degrees(axis, angle):
    # Near 180° w -> 0: the x, y and z Shepperd branches must take over.
    R = axis_angle(axis, angle)
    q = rotation_to_quaternion(R)
    torch.testing.assert_close(quaternion_to_rotation(q), R, atol=1e-12, rtol=0)
    k = torch.tensor(axis, dtype=torch.float64) / torch.tensor(axis, dtype=torch.float64).norm()
    expected = torch.cat([k * math.sin(angle / 2), torch.tensor([math.cos(angle / 2)], dtype=torch.float64)])
    assert torch.allclose(q, expected, atol=1e-12) or (angle == math.pi and torch.allclose(q, -expected, atol=1e-12))


def test_q_and_minus_q_are_the_same_rotation():
    q = torch.randn(50, 4, dtype=torch.float64)
    torch.testing.assert_close(quaternion_to_rotation(q), quaternion_to_rotation(-q))
    # quaternion_to_rotation normalises, rotation_to_quaternion picks the w >= 0 sign
    canonical = q / q.norm(dim=-1, keepdim=True) * torch.sign(q[:, 3:])
    torch.testing.assert_close(rotation_to_quaternion(quaternion_to_rotation(-q)), canonical)


def test_slerp_endpoints_and_midpoint():
    q0 = torch.tensor([0.0, 0.0, 0.0, 1.0], dtype=torch.float64)
    q1 = rotation_to_quaternion(axis_angle([0, 0, 1], math.pi / 2))
    torch.testing.assert_close(slerp(q0, q1, 0.0), q0)
    torch.testing.assert_close(slerp(q0, q1, 1.0), q1)
    torch.testing.assert_close(quaternion_to_rotation(slerp(q0, q1, 0.5)), axis_angle([0, 0, 1], math.pi / 4))


def test_slerp_takes_the_short_way_for_negated_quaternions():
    q0 = torch.tensor([0.0, 0.0, 0.0, 1.0], dtype=torch.float64)
    q1 = -rotation_to_quaternion(axis_angle([0, 0, 1], math.pi / 2))  # same rotation, other hemisphere
    torch.testing.assert_close(quaternion_to_rotation(slerp(q0, q1, 0.5)), axis_angle([0, 0, 1], math.pi / 4))


def test_slerp_constant_angular_rate():
    q0 = rotation_to_quaternion(axis_angle([1, 2, 3], 0.2))
    q1 = rotation_to_quaternion(axis_angle([-1, 0, 2], 2.5))
    alpha = torch.linspace(0, 1, 11, dtype=torch.float64)
    q = slerp(q0.expand(11, 4), q1.expand(11, 4), alpha)
    angle_from_start = 2 * torch.acos((q * q0).sum(-1).abs().clamp(max=1))
    torch.testing.assert_close(angle_from_start, alpha * angle_from_start[-1])


def test_slerp_nearly_equal_quaternions():
    q0 = rotation_to_quaternion(axis_angle([0, 0, 1], 0.3))
    q1 = rotation_to_quaternion(axis_angle([0, 0, 1], 0.3 + 1e-9))
    q = slerp(q0, q1, 0.5)
    assert torch.isfinite(q).all()
    torch.testing.assert_close(q, q0, atol=1e-9, rtol=0)
    assert torch.isfinite(slerp(q0, q0, torch.tensor(0.3, dtype=torch.float64))).all()


def test_interpolate_pose():
    T0 = make_transform(axis_angle([0, 0, 1], 0.0), torch.tensor([0.0, 0.0, 0.0], dtype=torch.float64))
    T1 = make_transform(axis_angle([0, 0, 1], math.pi / 2), torch.tensor([2.0, 4.0, -6.0], dtype=torch.float64))
    torch.testing.assert_close(interpolate_pose(T0, T1, 0.0), T0)
    torch.testing.assert_close(interpolate_pose(T0, T1, 1.0), T1)
    mid = interpolate_pose(T0, T1, 0.5)
    torch.testing.assert_close(mid[:3, 3], torch.tensor([1.0, 2.0, -3.0], dtype=torch.float64))
    torch.testing.assert_close(mid[:3, :3], axis_angle([0, 0, 1], math.pi / 4))


def test_interpolate_pose_batched():
    T0, T1 = random_poses(6, seed=5), random_poses(6, seed=6)
    alpha = torch.rand(6, dtype=torch.float64)
    T = interpolate_pose(T0, T1, alpha)
    assert T.shape == (6, 4, 4)
    for i in range(6):
        torch.testing.assert_close(T[i], interpolate_pose(T0[i], T1[i], alpha[i]))
    # one alpha for the whole batch, and one pose against a batch
    assert interpolate_pose(T0, T1, 0.25).shape == (6, 4, 4)
    assert interpolate_pose(T0[0], T1, alpha).shape == (6, 4, 4)
    torch.testing.assert_close(interpolate_pose(T0, T1, torch.ones(6, dtype=torch.float64)), T1)
