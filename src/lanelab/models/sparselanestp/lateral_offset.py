"""A dense lateral-offset map and the line fit that reads it: initial lane points from the image.

Why (issue "Decoders that read the road"): a DETR-style decoder trained from scratch on a few
thousand windows learns which lanes exist long before it learns where they lie; its lines stay
on a learned template (a response of ~0 to a sideways shift of the image). What reads fast is a
dense target and a direct read of it: this module's head predicts, for every cell of a feature
map, how far across the image the nearest visible lane lies from the ground point under the
cell (along the cell's row, as a fraction of the image width), and a confidence that there is
one within a few metres (trained by :class:`lanelab.models.sparselanestp.LateralOffsetLoss`; LATR's
instance-aware initial points in spirit, with a dense target as HDMapNet-style heads have).
The offset is in image units, not metres: across a lane it is linear in both image axes, so
bilinear reading is exact, where metres would mix rows of different scale (a read near a lane
would be biased by up to half a metre on a stride-4 map); the read converts to metres with the
image's own scale at the point (pixels per metre sideways).

Reading (:meth:`LateralOffsetReader.line_shifts`): each line samples the map where its current
curve crosses the near range (``read_range``, where a small image shows lane positions), and a
weighted least-squares fit of the read offsets, offset + heading per line, moves all its
control points. The fit is what makes the far control points follow: they sit near the horizon, where the image
no longer says where a lane is, and move by the fit at the end of the read range (a heading read
over 25 m and extrapolated to 100 m would throw them metres off for a few centimetres of error;
what the image says beyond, the decoder's layers read). A line that reads nothing (its samples outside the image, or no confidence)
keeps its points: the correction starts at zero, so an untrained reader changes nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lanelab.geometry import project_lane_points

# Ridge of the per-line fit: an offset or heading read from fewer than about this many confident
# samples is shrunk toward "no correction".
_RIDGE = 0.1


class LateralOffsetReader(nn.Module):
    """embed_dim C: channels of the FPN level it reads; fine_channels: channels of the stride-4
    backbone map merged in (the map is then at stride 4, else at the FPN level's stride 8), or
    None; hidden: channels of the head; read_range: (near, far) metres of lane the lines read; num_reads: samples per
    line in that range; iterations: read-and-fit rounds (each reads where the last one moved
    the line)."""

    def __init__(
        self,
        embed_dim: int,
        fine_channels: int | None,
        hidden: int,
        read_range: Sequence[float],
        num_reads: int,
        iterations: int,
    ) -> None:
        super().__init__()
        self.fine = None if fine_channels is None else nn.Conv2d(fine_channels, embed_dim, 1)
        self.head = nn.Sequential(
            nn.Conv2d(embed_dim, hidden, 3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(hidden, hidden, 3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(hidden, 2, 1),
        )
        # Start at "offset 0, unsure": an untrained reader moves no line.
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)
        self.iterations = int(iterations)
        near, far = (float(v) for v in read_range)
        if not 0 < near < far:
            raise ValueError(f"read_range must be (near, far) metres with 0 < near < far, got {tuple(read_range)}")
        # Buffers, not host tensors per call: a streaming step stays capturable (CUDA graphs).
        self.register_buffer("read_y", torch.linspace(near, far, num_reads), persistent=False)
        self.register_buffer("unit_x", torch.tensor([1.0, 0.0, 0.0]), persistent=False)
        self.centre, self.half_span = (near + far) / 2, (far - near) / 2

    def forward(self, feature: Tensor, fine: Tensor | None = None) -> Tensor:
        """feature (B, C, h, w), the finest FPN level; fine (B, c, 2h, 2w) the stride-4 backbone
        map when the reader has fine_channels. Returns the map (B, 2, h', w'): channel 0 the
        offset to the nearest lane along the row, in image widths (in ±1), channel 1 the
        confidence logit."""
        if self.fine is not None:
            if fine is None:
                raise ValueError("this LateralOffsetReader reads a stride-4 map: pass the backbone's C2")
            feature = self.fine(fine) + F.interpolate(feature, size=fine.shape[-2:], mode="bilinear", align_corners=False)
        raw = self.head(feature)
        return torch.cat([torch.tanh(raw[:, :1]), raw[:, 1:]], dim=1)

    def read(
        self, offset_map: Tensor, points: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> tuple[Tensor, Tensor]:
        """Sample the map at lane-frame points (B, N, S, 3): offsets (B, N, S) in metres of
        lane-frame x and weights (B, N, S) in [0, 1] (the confidence times the read's relative
        precision; 0 outside the image or behind the camera)."""
        B, N, S, _ = points.shape
        height, width = image_size
        dtype = torch.promote_types(points.dtype, torch.float32)
        with torch.autocast(points.device.type, enabled=False):
            points = points.flatten(1, 2).to(dtype)
            K, T_lane_cam = K.to(dtype), T_lane_cam.to(dtype)
            uv, _, in_front = project_lane_points(points, K, T_lane_cam)
            sideways, _, _ = project_lane_points(points + self.unit_x.to(dtype), K, T_lane_cam)
            widths_per_metre = (sideways[..., 0] - uv[..., 0]) / width  # the image's scale at each point
            u, v = uv.unbind(-1)
            inside = in_front & (u >= 0) & (u <= width) & (v >= 0) & (v <= height) & (widths_per_metre.abs() > 1e-6)
            grid = torch.stack([u / width, v / height], -1).nan_to_num(0.5) * 2 - 1
            # Normalised convolution: cells unsure of a lane (whose offsets nothing trained) do not
            # pull a read near them toward their values.
            confidence = offset_map[:, 1:].to(dtype).sigmoid()
            weighted = torch.cat([offset_map[:, :1].to(dtype) * confidence, confidence], 1)
            sampled = F.grid_sample(weighted, grid[:, None], align_corners=False)[:, :, 0]  # (B, 2, N S)
            read = sampled[:, 0] / sampled[:, 1].clamp_min(1e-6)
            metres = read / torch.where(inside, widths_per_metre, torch.ones_like(widths_per_metre))
        offsets = torch.where(inside, metres, torch.zeros_like(metres)).view(B, N, S)
        # Inverse variance: a read's error is about constant in pixels, so in metres it grows with
        # the distance; relative to the line's sharpest read, so that the weights stay in [0, 1].
        precision = torch.where(inside, widths_per_metre.abs(), torch.zeros_like(widths_per_metre)).view(B, N, S)
        precision = precision / precision.amax(-1, keepdim=True).clamp_min(1e-6)
        weights = sampled[:, 1].view(B, N, S) * precision.square()
        return offsets, weights

    def line_shifts(
        self,
        offset_map: Tensor,
        curve: Callable[[Tensor], Tensor],
        y: Tensor,
        K: Tensor,
        T_lane_cam: Tensor,
        image_size: tuple[int, int],
    ) -> Tensor:
        """How far to move each line's control points sideways, (B, N, M) metres.

        curve: maps per-line x shifts (B, N, M) of the control points (at y (M,)) to the lines'
        points (B, N, S, 3) at ``read_y`` (the caller's curve representation). Each round reads
        the map along the shifted lines and adds the fit: offset a + heading b (y - centre), with y
        no further than the read range's far end."""
        t_read = (self.read_y - self.centre) / self.half_span  # (S,)
        t_points = ((y - self.centre) / self.half_span).clamp(max=1.0)  # (M,); beyond the range: its far end
        shifts = y.new_zeros(1)
        for _ in range(self.iterations):
            offsets, weights = self.read(offset_map, curve(shifts), K, T_lane_cam, image_size)
            a, b = _weighted_line_fit(t_read.to(offsets), offsets, weights)
            shifts = shifts + a[..., None] + b[..., None] * t_points.to(a)
        return shifts


def _weighted_line_fit(t: Tensor, d: Tensor, w: Tensor) -> tuple[Tensor, Tensor]:
    """Ridge least squares d ≈ a + b t over the last axis: t (S,), d, w (..., S) -> a, b (...).
    The 2 x 2 normal equations are solved in closed form (exportable, no linalg call)."""
    s0 = w.sum(-1) + _RIDGE
    s1 = (w * t).sum(-1)
    s2 = (w * t * t).sum(-1) + _RIDGE
    r0, r1 = (w * d).sum(-1), (w * t * d).sum(-1)
    determinant = s0 * s2 - s1 * s1
    return (s2 * r0 - s1 * r1) / determinant, (s0 * r1 - s1 * r0) / determinant
