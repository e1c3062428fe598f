"""Rigid transforms, rotations and quaternions, batched over any leading dimensions.

A pose is a homogeneous (..., 4, 4) tensor. ``T_a_b`` maps points expressed in frame b into
frame a, so ``T_a_c = compose(T_a_b, T_b_c)``. Quaternions use the ROS order (x, y, z, w).
"""

from __future__ import annotations

from functools import reduce

import torch
from torch import Tensor

# Below this angle between two unit quaternions slerp's sin(theta) denominator loses precision;
# normalised lerp is then exact to ~theta^3, far below float precision.
_SLERP_MIN_ANGLE = 1e-4


def make_transform(R: Tensor, t: Tensor) -> Tensor:
    """Homogeneous transform from rotation R (..., 3, 3) and translation t (..., 3) -> (..., 4, 4).

    The batch dimensions of R and t broadcast.
    """
    batch = torch.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    top = torch.cat([R.expand(*batch, 3, 3), t.expand(*batch, 3).unsqueeze(-1)], dim=-1)
    bottom = torch.cat([R.new_zeros(3), R.new_ones(1)])  # on R's device: no host copy (CUDA graphs capture none)
    return torch.cat([top, bottom.expand(*batch, 1, 4)], dim=-2)


def invert(T: Tensor) -> Tensor:
    """Inverse of rigid transforms T (..., 4, 4): [R^T, -R^T t], exact where torch.inverse is not."""
    R_inv = T[..., :3, :3].transpose(-1, -2)
    t = T[..., :3, 3:]
    return make_transform(R_inv, -(R_inv @ t).squeeze(-1))


def compose(*Ts: Tensor) -> Tensor:
    """Product T_0 @ T_1 @ ... of (..., 4, 4) transforms, left to right, batch dims broadcasting."""
    if not Ts:
        raise ValueError("compose needs at least one transform")
    return reduce(torch.matmul, Ts)


def transform_points(T: Tensor, points: Tensor) -> Tensor:
    """Apply T (..., 4, 4) to points (..., N, 3) -> (..., N, 3)."""
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    # A contiguous R^T: the CPU's batched product over many points is then about twice as fast.
    return points @ R.transpose(-1, -2).contiguous() + t.unsqueeze(-2)


def euler_to_rotation(roll: Tensor, pitch: Tensor, yaw: Tensor) -> Tensor:
    """Rotation matrices (..., 3, 3) from ROS fixed-axis angles: R = Rz(yaw) @ Ry(pitch) @ Rx(roll).

    roll, pitch, yaw: (...) tensors of broadcastable shapes, radians.
    """
    roll, pitch, yaw = torch.broadcast_tensors(roll, pitch, yaw)
    cr, sr = roll.cos(), roll.sin()
    cp, sp = pitch.cos(), pitch.sin()
    cy, sy = yaw.cos(), yaw.sin()
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def rotation_to_quaternion(R: Tensor) -> Tensor:
    """Unit quaternions (..., 4) in (x, y, z, w) order from rotation matrices (..., 3, 3).

    Shepperd's method: of the four algebraically equivalent formulas, each batch element uses
    the one whose pivot (4w², 4x², 4y² or 4z²) is largest, so it never divides by a small
    number (e.g. near 180° rotations, where w -> 0). Sign is canonical: w >= 0.
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (row.unbind(-1) for row in R.unbind(-2))
    pivots = torch.stack(
        [1 + r00 + r11 + r22, 1 + r00 - r11 - r22, 1 - r00 + r11 - r22, 1 - r00 - r11 + r22], dim=-1
    )
    # Row i is 4 q_i q for the pivot component q_i in (w, x, y, z); its norm is 4 |q_i|.
    candidates = torch.stack(
        [
            torch.stack([r21 - r12, r02 - r20, r10 - r01, pivots[..., 0]], dim=-1),
            torch.stack([pivots[..., 1], r01 + r10, r02 + r20, r21 - r12], dim=-1),
            torch.stack([r01 + r10, pivots[..., 2], r12 + r21, r02 - r20], dim=-1),
            torch.stack([r02 + r20, r12 + r21, pivots[..., 3], r10 - r01], dim=-1),
        ],
        dim=-2,
    )
    best = pivots.argmax(dim=-1)[..., None, None]
    q = torch.take_along_dim(candidates, best, dim=-2).squeeze(-2)
    q = q / q.norm(dim=-1, keepdim=True)
    return torch.where(q[..., 3:] < 0, -q, q)


def quaternion_to_rotation(q: Tensor) -> Tensor:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) in (x, y, z, w) order, normalised first."""
    x, y, z, w = (q / q.norm(dim=-1, keepdim=True)).unbind(-1)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def slerp(q0: Tensor, q1: Tensor, alpha: Tensor | float) -> Tensor:
    """Spherical linear interpolation of unit quaternions (..., 4), shortest path.

    alpha: (...) tensor broadcastable with the quaternions' batch dims, or a float;
    0 gives q0, 1 gives q1 (or -q1, the same rotation). Nearly equal quaternions use
    normalised lerp.
    """
    q0 = q0 / q0.norm(dim=-1, keepdim=True)
    q1 = q1 / q1.norm(dim=-1, keepdim=True)
    # q and -q are the same rotation: take the one on q0's hemisphere for the short way round.
    q1 = torch.where((q0 * q1).sum(-1, keepdim=True) < 0, -q1, q1)
    alpha = torch.as_tensor(alpha, dtype=q0.dtype, device=q0.device).unsqueeze(-1)
    # atan2 keeps the angle accurate for nearly equal quaternions, where acos(dot) does not.
    theta = 2 * torch.atan2((q0 - q1).norm(dim=-1, keepdim=True), (q0 + q1).norm(dim=-1, keepdim=True))
    small = theta < _SLERP_MIN_ANGLE
    sin_theta = torch.where(small, torch.ones_like(theta), theta.sin())
    w0 = torch.where(small, 1 - alpha, ((1 - alpha) * theta).sin() / sin_theta)
    w1 = torch.where(small, alpha, (alpha * theta).sin() / sin_theta)
    q = w0 * q0 + w1 * q1
    return q / q.norm(dim=-1, keepdim=True)


def interpolate_pose(T0: Tensor, T1: Tensor, alpha: Tensor | float) -> Tensor:
    """Pose between T0 and T1 (..., 4, 4): linear in translation, slerp in rotation.

    alpha: (...) tensor or float, 0 gives T0 and 1 gives T1.
    """
    alpha = torch.as_tensor(alpha, dtype=T0.dtype, device=T0.device)
    q = slerp(rotation_to_quaternion(T0[..., :3, :3]), rotation_to_quaternion(T1[..., :3, :3]), alpha)
    a = alpha.unsqueeze(-1)
    t = (1 - a) * T0[..., :3, 3] + a * T1[..., :3, 3]
    return make_transform(quaternion_to_rotation(q), t)
