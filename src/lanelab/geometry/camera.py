"""Pinhole camera: projection, back-projection and ray-ground intersection.

Camera frame = OpenCV optical frame (x right, y down, z forward); K (..., 3, 3) is in pixels.
Pixel coordinates follow the pixel-centre convention: pixel (i, j) covers
[i, i + 1) x [j, j + 1), so a point is in an image of size (width, height) when
0 <= u < width and 0 <= v < height.
"""

from __future__ import annotations

import torch
from torch import Tensor

from lanelab.geometry.transforms import invert, transform_points

# Metres: points nearer the camera plane than this count as behind the camera.
MIN_DEPTH = 1e-3


def project(points_cam: Tensor, K: Tensor, min_depth: float = MIN_DEPTH) -> tuple[Tensor, Tensor]:
    """Project camera-frame points (..., N, 3) with K (..., 3, 3).

    Returns uv (..., N, 2) and in_front (..., N) bool. Points with z <= min_depth are flagged
    (in_front False) and get NaN uv, instead of being projected through the mirror.
    """
    z = points_cam[..., 2:]
    in_front = z > min_depth
    # Dividing by 1 where flagged keeps NaN/inf out of gradients of the valid points.
    homogeneous = points_cam @ K.transpose(-1, -2).contiguous()  # contiguous: as in transform_points
    uv = homogeneous[..., :2] / torch.where(in_front, z, torch.ones_like(z))
    uv = torch.where(in_front, uv, torch.full_like(uv, float("nan")))
    return uv, in_front.squeeze(-1)


def project_lane_points(
    points_lane: Tensor, K: Tensor, T_lane_cam: Tensor, min_depth: float = MIN_DEPTH
) -> tuple[Tensor, Tensor, Tensor]:
    """Project lane-frame points (..., N, 3) into a camera with extrinsic T_lane_cam (..., 4, 4).

    Returns uv (..., N, 2) (NaN where not in front), depth (..., N) along the optical axis and
    in_front (..., N) bool.
    """
    points_cam = transform_points(invert(T_lane_cam), points_lane)
    uv, in_front = project(points_cam, K, min_depth)
    return uv, points_cam[..., 2], in_front


def in_image(uv: Tensor, width: int, height: int) -> Tensor:
    """(..., N) bool: uv (..., N, 2) lies inside a width x height image; NaN gives False."""
    u, v = uv.unbind(-1)
    return (u >= 0) & (u < width) & (v >= 0) & (v < height)


def image_extent(size: tuple[int, int], dtype: torch.dtype, device: torch.device | str) -> Tensor:
    """(2,) = (width, height) of an image or map of size (H, W): what divides pixel positions
    (u, v) into [0, 1]. Filled on the device (one kernel), not copied from host data as
    ``torch.tensor`` would: a streaming step stays capturable as a CUDA graph."""
    height, width = size
    return torch.linspace(width, height, 2, dtype=dtype, device=device)


def cell_centres(
    map_size: tuple[int, int], image_size: tuple[int, int], dtype: torch.dtype, device: torch.device | str
) -> Tensor:
    """Pixel centres (h w, 2) = (u, v), row-major, of the cells of an (h, w) map covering an image of
    image_size (H, W): cell (i, j) covers pixels [j, j + 1) * W / w (the pixel-area convention)."""
    (h, w), (height, width) = map_size, image_size
    v = (torch.arange(h, device=device, dtype=dtype) + 0.5) * (height / h)
    u = (torch.arange(w, device=device, dtype=dtype) + 0.5) * (width / w)
    return torch.stack(torch.meshgrid(u, v, indexing="xy"), -1).reshape(h * w, 2)


def pixel_rays(uv: Tensor, K: Tensor) -> Tensor:
    """Camera-frame rays (..., N, 3) through pixels uv (..., N, 2), scaled to z = 1: K^-1 [u, v, 1]."""
    # K is upper triangular: back substitution, written out (exact, cheaper than an inverse, and
    # exportable: ONNX has no triangular solve). Rays at z = 1 need no third row.
    k = K.unsqueeze(-3)  # (..., 1, 3, 3), broadcast over the N pixels
    u, v = uv.unbind(-1)
    y = (k[..., 2, 2] * v - k[..., 1, 2]) / k[..., 1, 1]
    x = (k[..., 2, 2] * u - k[..., 0, 1] * y - k[..., 0, 2]) / k[..., 0, 0]
    return torch.stack([x, y, torch.ones_like(x)], dim=-1)


def backproject(uv: Tensor, depth: Tensor, K: Tensor) -> Tensor:
    """Camera-frame points (..., N, 3) at pixels uv (..., N, 2) and depths (..., N) along z."""
    return pixel_rays(uv, K) * depth.unsqueeze(-1)


def backproject_to_lane(uv: Tensor, depth: Tensor, K: Tensor, T_lane_cam: Tensor) -> Tensor:
    """Lane-frame points (..., N, 3) at pixels uv (..., N, 2) and camera depths (..., N)."""
    return transform_points(T_lane_cam, backproject(uv, depth, K))


def intersect_ground(
    uv: Tensor, K: Tensor, T_lane_cam: Tensor, ground_z: float | Tensor = 0.0
) -> tuple[Tensor, Tensor]:
    """Intersect the rays of pixels uv (..., N, 2) with the plane z_L = ground_z.

    ground_z: float or tensor broadcastable to (..., N). Returns points_lane (..., N, 3) and
    valid (..., N) bool; where the ray is parallel to or points away from the plane, valid is
    False and the points are NaN.
    """
    rays = pixel_rays(uv, K) @ T_lane_cam[..., :3, :3].transpose(-1, -2)  # directions in lane frame
    origin = T_lane_cam[..., :3, 3].unsqueeze(-2)  # (..., 1, 3) camera centre
    rise = rays[..., 2]
    parallel = rise.abs() <= torch.finfo(rise.dtype).eps
    # Rays have unit camera depth, so the ray parameter is the depth of the hit point.
    depth = (ground_z - origin[..., 2]) / torch.where(parallel, torch.ones_like(rise), rise)
    valid = ~parallel & (depth > 0)
    points = origin + depth.unsqueeze(-1) * rays
    points = torch.where(valid.unsqueeze(-1), points, torch.full_like(points, float("nan")))
    return points, valid
