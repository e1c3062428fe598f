"""ROS ``base_link`` (x forward, y left, z up) <-> lane frame (x right, y forward, z up).

Both frames share the origin (on the ground under the rear axle); only the axes differ:
x_L = -y_b, y_L = x_b, z_L = z_b. See DESIGN.md, "Coordinate frames and units".
"""

from __future__ import annotations

import torch
from torch import Tensor

# Rotation of T_base_lane: its columns are the lane axes expressed in base_link.
_R_BASE_LANE = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))


def base_lane_transform(dtype: torch.dtype = torch.float64, device: torch.device | str | None = None) -> Tensor:
    """T_base_lane (4, 4): maps lane-frame points into base_link."""
    T = torch.eye(4, dtype=dtype, device=device)
    T[:3, :3] = torch.tensor(_R_BASE_LANE, dtype=dtype, device=device)
    return T


def lane_base_transform(dtype: torch.dtype = torch.float64, device: torch.device | str | None = None) -> Tensor:
    """T_lane_base (4, 4): maps base_link points into the lane frame (inverse of T_base_lane)."""
    return base_lane_transform(dtype, device).transpose(0, 1)


# float64 constants for convenience; the functions above give other dtypes and devices.
T_BASE_LANE = base_lane_transform()
T_LANE_BASE = lane_base_transform()


def base_link_to_lane(points: Tensor) -> Tensor:
    """Points (..., N, 3) in base_link -> (..., N, 3) in the lane frame (exact, no arithmetic)."""
    x, y, z = points.unbind(-1)
    return torch.stack([-y, x, z], dim=-1)


def lane_to_base_link(points: Tensor) -> Tensor:
    """Points (..., N, 3) in the lane frame -> (..., N, 3) in base_link."""
    x, y, z = points.unbind(-1)
    return torch.stack([y, -x, z], dim=-1)


def pose_base_to_lane(T_world_base: Tensor) -> Tensor:
    """Ego pose T_world_base (..., 4, 4) -> T_world_lane (..., 4, 4) = T_world_base @ T_base_lane."""
    return T_world_base @ base_lane_transform(T_world_base.dtype, T_world_base.device)


def extrinsic_base_to_lane(T_base_cam: Tensor) -> Tensor:
    """Camera extrinsic T_base_cam (..., 4, 4) -> T_lane_cam (..., 4, 4) = T_lane_base @ T_base_cam."""
    return lane_base_transform(T_base_cam.dtype, T_base_cam.device) @ T_base_cam
