"""Bi²Lane's 3D anchors: their families, their projection into a frame's front-view features and
the sampling of those features there (eq. 1), and their motion from frame to frame (eq. 3).

The paper defines the i-th anchor as M 3D points at fixed y (§III-A.1) and says no more; as
Anchor3DLane (whose anchors and projection the paper builds on) each anchor is a straight ray
from a start x on the ground at y = 0, turned by a yaw and raised by a pitch:
    x(y) = x_start + y tan(yaw),   z(y) = y tan(pitch),
one anchor per (start x, pitch, yaw) of the configured families, in that order, keeping those
with at least half of their points inside the lateral range (Anchor3DLane's cut).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import Tensor

from lanelab.geometry import compose, invert, transform_points
from lanelab.geometry.camera import MIN_DEPTH

# Normalised sampling coordinate of points behind the camera: outside [-1, 1], so grid_sample's
# zero padding gives them no feature.
_OUTSIDE = -2.0
# Sampled values from which the CPU's weighted-sum path beats grid_sample and its transposing copy
# (the paper's BDTR step samples 11 M, the tiny one's 50 k; measured by benchmarks/bench_bi2lane.py).
_LARGE_SAMPLE = 1 << 20


def anchor_families(
    y: Tensor, x_range: Sequence[float], num_x: int, yaws: Sequence[float], pitches: Sequence[float]
) -> Tensor:
    """Anchors (A, M, 3) = (x, y, z), lane frame, at the longitudinal positions y (M,): start x
    evenly over x_range (num_x of them), yaws and pitches in degrees (module doc)."""
    if num_x < 1 or not yaws or not pitches:
        raise ValueError(f"anchors need num_x >= 1 and at least one yaw and pitch, got {num_x}, {yaws}, {pitches}")
    low, high = x_range
    starts = torch.linspace(low, high, num_x, dtype=y.dtype)
    anchors = []
    for start in starts.tolist():
        for pitch in pitches:
            for yaw in yaws:
                x = start + y * math.tan(math.radians(yaw))
                z = y * math.tan(math.radians(pitch))
                if ((x > low) & (x < high)).float().mean() >= 0.5:
                    anchors.append(torch.stack([x, y, z], dim=-1))
    if not anchors:
        raise ValueError(f"no anchor keeps half of its points inside x_range {tuple(x_range)}")
    return torch.stack(anchors)


def sampling_grid(points: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]) -> Tensor:
    """P_g2l of eq. 1: lane-frame points (B, ..., 3) seen by the camera K (B, 3, 3), T_lane_cam
    (B, 4, 4) of images of image_size (H, W) -> grid_sample coordinates (B, ..., 2) in [-1, 1]
    over the image (align_corners=False: -1 and 1 are the image's outer edges), outside it for
    points behind the camera. Computed in float32 at least, outside autocast."""
    dtype = torch.promote_types(points.dtype, K.dtype)
    return project_to_grid(points, grid_projection(K.to(dtype), T_lane_cam, image_size))


def grid_projection(K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]) -> Tensor:
    """The projection of :func:`sampling_grid` as one matrix (..., 4, 3), float32 at least: N K T_cam_lane
    transposed, N the pixels' normalisation to [-1, 1], so that lane-frame points p (3,) have the
    homogeneous grid coordinates p P[:3] + P[3]. K (..., 3, 3), T_lane_cam (..., 4, 4) of images of
    image_size (H, W). BDTR projects for all its steps at once, then per step only the points."""
    dtype = torch.promote_types(K.dtype, torch.float32)
    with torch.autocast(K.device.type, enabled=False):
        height, width = image_size
        # N K row by row (u -> 2 u / W - 1): a matrix made on the host could not be captured in a CUDA graph.
        rows = K.to(dtype).unbind(-2)
        NK = torch.stack([rows[0] * (2 / width) - rows[2], rows[1] * (2 / height) - rows[2], rows[2]], -2)
        return (NK @ invert(T_lane_cam.to(dtype))[..., :3, :]).transpose(-1, -2).contiguous()


def project_to_grid(points: Tensor, P: Tensor) -> Tensor:
    """Lane-frame points (B, ..., 3) -> grid_sample coordinates (B, ..., 2) by P (B, 4, 3) of
    :func:`grid_projection` (as :func:`sampling_grid`): one product and one division a point,
    in the wider of the two dtypes."""
    shape = points.shape
    dtype = torch.promote_types(points.dtype, P.dtype)
    with torch.autocast(points.device.type, enabled=False):
        flat, P = points.reshape(shape[0], -1, 3).to(dtype), P.to(dtype)
        homogeneous = torch.baddbmm(P[:, 3:], flat, P[:, :3])
        depth = homogeneous[..., 2:]  # K's last row is (0, 0, 1): the depth along the optical axis
        # Clamped, the division stays finite behind the camera: no inf / NaN in the gradients of the points in front.
        grid = (homogeneous[..., :2] / depth.clamp(min=MIN_DEPTH)).masked_fill_(depth <= MIN_DEPTH, _OUTSIDE)
    return grid.reshape(*shape[:-1], 2)


def sample_features(features: Tensor, grid: Tensor) -> Tensor:
    """S of eq. 1: feature maps (B, C, h, w) covering the image, bilinearly sampled at grid
    (B, A, M, 2) of :func:`sampling_grid` -> (B, A, M, C); zero outside the image.

    Large samples on the CPU (outside ONNX export) are a weighted sum of each point's four
    neighbouring feature vectors in a channels-last map (``embedding_bag``), which gives the
    (A, M, C) layout the heads read directly; ``grid_sample`` gives (C, A, M), and at the paper's
    4431 x 20 points its transposing copy cost as much as the sampling (BDTR samples once per
    history frame). Small samples, and other devices, take grid_sample's one call (on an H100 the
    weighted sum was the slower: benchmarks/RESULTS.md). Both compute grid_sample's bilinear
    interpolation (align_corners=False, zero padding)."""
    large = grid[..., 0].numel() * features.shape[1] >= _LARGE_SAMPLE
    if not large or features.device.type != "cpu" or torch.onnx.is_in_onnx_export():
        sampled = F.grid_sample(features, grid.to(features.dtype), mode="bilinear", padding_mode="zeros",
                                align_corners=False)  # fmt: skip
        return sampled.permute(0, 2, 3, 1)
    B, C, h, w = features.shape
    grid = grid.to(torch.promote_types(features.dtype, torch.float32))  # row indices are exact in float32
    # A zero border around the map: the neighbours outside it read zeros, as grid_sample's padding.
    table = F.pad(features, (1, 1, 1, 1)).permute(0, 2, 3, 1).reshape(-1, C)
    # Per axis, contiguous: broadcasting over a trailing axis of two is several times slower.
    column, right = _neighbours(grid[..., 0], w)
    row, down = _neighbours(grid[..., 1], h)
    left, up = 1 - right, 1 - down
    weights = torch.stack([up * left, up * right, down * left, down * right], -1).to(features.dtype)
    # Rows of the padded table: the upper left neighbour's (+1 for the border), then its right, lower and diagonal ones.
    first = row * (w + 2) + column
    stream = torch.arange(B, device=grid.device, dtype=grid.dtype) * ((h + 2) * (w + 2)) + (w + 3)
    first = first + stream.view(B, *[1] * (first.dim() - 1))
    rows = (first.unsqueeze(-1) + grid.new_tensor([0.0, 1.0, w + 2.0, w + 3.0])).int()
    sampled = F.embedding_bag(rows.view(-1, 4), table, per_sample_weights=weights.view(-1, 4), mode="sum")
    return sampled.view(*grid.shape[:-1], C)


def _neighbours(coordinate: Tensor, size: int) -> tuple[Tensor, Tensor]:
    """Normalised coordinates (...) along an axis of ``size`` cells -> the lower of the two
    neighbouring cells (...) and the upper one's bilinear weight (...). Points beyond the map are
    clamped into the zero border, so that they read only zeros."""
    pixel = (coordinate.nan_to_num(_OUTSIDE) * (size / 2) + (size / 2 - 0.5)).clamp(-1.0, size)  # cell centres at integers
    lower = pixel.floor().clamp_(max=size - 1)
    return lower, pixel - lower


def ego_motion(T_world_lane_to: Tensor, T_world_lane_from: Tensor) -> Tensor:
    """T_{from -> to} of eq. 3 (B, 4, 4): maps lane-frame points of one frame into another's,
    T_world_lane(to)^-1 · T_world_lane(from), in the poses' precision (float64: world
    coordinates reach kilometres)."""
    return compose(invert(T_world_lane_to), T_world_lane_from.to(T_world_lane_to))


def move_points(T: Tensor, points: Tensor) -> Tensor:
    """Points (..., A, M, 3) moved by T (..., 4, 4) (e.g. :func:`ego_motion`), in their own dtype."""
    return transform_points(T.to(points.dtype), points.flatten(-3, -2)).view(points.shape)
