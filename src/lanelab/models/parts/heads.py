"""Prediction heads shared by all decoder layers (SparseLaneSTP eq. 5-7) and the lane representation.

Every query (line i, point j) carries a control point P_ij = (x, y, z, v):
    x = sigmoid(MLP_x(Q_ij)) * (x_e - x_s) + x_s        (eq. 5)
    z = sigmoid(MLP_z(Q_ij)) * (z_e - z_s) + z_s        (eq. 6)
    v = sigmoid(MLP_v(Q_ij))                            (eq. 7)
    y = fixed, uniform in [y_s, y_e]                    (control_point_y)
Layers refine x and z iteratively as LATR / Deformable DETR do: each layer adds its MLP
outputs to the previous layer's pre-sigmoid values ("logits" below), so a layer predicts a
correction, and eq. 5-6 hold with MLP(Q) standing for the accumulated sum. Visibility is
predicted afresh by every layer, as in LATR (and literally eq. 7).

The M points decode in either representation of :mod:`lanelab.geometry.curves` (Catmull-Rom
control points, §3.1, or LATR's discrete points; the ablation of Table 1).

Classification averages the M queries of a line and maps them to K categories + background
(:mod:`lanelab.models.categories`).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from lanelab.geometry import control_point_y
from lanelab.geometry.curves import LaneCurves


def mlp(in_dim: int, hidden_dim: int, out_dim: int, num_hidden: int) -> nn.Sequential:
    """``num_hidden`` Linear+ReLU layers, then a Linear to out_dim (LATR's branch layout)."""
    layers: list[nn.Module] = []
    for i in range(num_hidden):
        layers += [nn.Linear(in_dim if i == 0 else hidden_dim, hidden_dim), nn.ReLU(inplace=True)]
    layers.append(nn.Linear(hidden_dim if num_hidden else in_dim, out_dim))
    return nn.Sequential(*layers)


def point_normaliser(
    x_range: tuple[float, float], y_range: tuple[float, float], z_range: tuple[float, float]
) -> Tensor:
    """(2, 4) scale and shift that map points (x, y, z, v) in metres by their (start, end)
    ranges to [0, 1] (v as is): ``normalise_points``'s constant, made once as a module's buffer."""
    low = torch.tensor([x_range[0], y_range[0], z_range[0], 0.0], dtype=torch.float64)
    high = torch.tensor([x_range[1], y_range[1], z_range[1], 1.0], dtype=torch.float64)
    scale = 1 / (high - low)
    return torch.stack([scale, -low * scale]).float()


def normalise_points(points: Tensor, normaliser: Tensor) -> Tensor:
    """Points (..., 4) = (x, y, z, v) in metres -> x, y, z mapped to [0, 1] by the ranges of
    normaliser (2, 4) (``point_normaliser``): the input of the positional encodings. One kernel."""
    return torch.addcmul(normaliser[1], points, normaliser[0])


class LaneHead(nn.Module):
    """Control points and classes from queries, shared across decoder layers.

    embed_dim C; num_points M; num_classes K (without background); x_range, y_range, z_range:
    (start, end) in metres; representation: "catmull_rom" or "discrete"; num_hidden: hidden
    layers of each MLP.
    """

    def __init__(
        self,
        embed_dim: int,
        num_points: int,
        num_classes: int,
        x_range: tuple[float, float],
        y_range: tuple[float, float],
        z_range: tuple[float, float],
        representation: str,
        num_hidden: int,
    ) -> None:
        super().__init__()
        self.curves = LaneCurves(representation, num_points, tuple(y_range))
        self.num_points, self.representation = num_points, representation
        self.x_range, self.y_range, self.z_range = tuple(x_range), tuple(y_range), tuple(z_range)
        # Three MLPs (eq. 5-7) and the classifier (K categories + background).
        self.x_mlp = mlp(embed_dim, embed_dim, 1, num_hidden)
        self.z_mlp = mlp(embed_dim, embed_dim, 1, num_hidden)
        self.v_mlp = mlp(embed_dim, embed_dim, 1, num_hidden)
        self.class_mlp = mlp(embed_dim, embed_dim, num_classes + 1, num_hidden)
        # Deformable DETR: refinements start at zero, so every layer first keeps the points it got.
        for branch in (self.x_mlp, self.z_mlp):
            nn.init.zeros_(branch[-1].weight)
            nn.init.zeros_(branch[-1].bias)
        # Non-persistent: derived from the configuration, not learned.
        self.register_buffer("y", control_point_y(num_points, *self.y_range), persistent=False)
        # control_points as one multiply-add: (x, y, z, v) = unit (x, x, z, v) * scale + shift,
        # scale (4,) = (x span, 0, z span, 1), shift (M, 4) = (x start, y_m, z start, 0).
        self.register_buffer("unit_channels", torch.tensor([0, 0, 1, 2]), persistent=False)
        (x_start, x_end), (z_start, z_end) = self.x_range, self.z_range
        self.register_buffer("unit_scale", torch.tensor([x_end - x_start, 0.0, z_end - z_start, 1.0]), persistent=False)
        shift = torch.tensor([x_start, 0.0, z_start, 0.0]).repeat(num_points, 1)
        shift[:, 1] = self.y
        self.register_buffer("unit_shift", shift, persistent=False)
        self.register_buffer("normaliser", point_normaliser(self.x_range, self.y_range, self.z_range), persistent=False)

    def refine(self, queries: Tensor, logits: Tensor) -> Tensor:
        """queries (B, N, M, C), previous pre-sigmoid (x, z, v) logits (B, N, M, 3) -> this
        layer's: x, z corrected, v replaced. In float32 even under bf16 autocast: 8 mantissa
        bits of a logit are decimetres of x."""
        x = logits[..., :1].float() + self.x_mlp(queries).float()
        z = logits[..., 1:2].float() + self.z_mlp(queries).float()
        return torch.cat([x, z, self.v_mlp(queries).float()], dim=-1)

    def shift_x(self, logits: Tensor, shift: Tensor) -> Tensor:
        """Pre-sigmoid (x, z, v) logits (..., M, 3) with x moved by shift (..., M) metres."""
        unit = logits[..., 0].float().sigmoid() + shift / (self.x_range[1] - self.x_range[0])
        x = torch.logit(unit.clamp(1e-6, 1 - 1e-6))
        return torch.cat([x[..., None].to(logits.dtype), logits[..., 1:]], dim=-1)

    def control_points(self, logits: Tensor) -> Tensor:
        """Pre-sigmoid (x, z, v) logits (..., M, 3) -> control points (..., M, 4) = (x, y, z, v),
        metres, at least float32."""
        unit = logits.to(torch.promote_types(logits.dtype, torch.float32)).sigmoid()
        return torch.addcmul(self.unit_shift, unit.index_select(-1, self.unit_channels), self.unit_scale)

    def point_logits(self, points: Tensor) -> Tensor:
        """Control points (..., M, 4) = (x, y, z, v), metres -> the pre-sigmoid (x, z, v) logits
        (..., M, 3) that ``control_points`` maps back to them, each clamped into its range."""
        channels = (0, 2, 3)
        unit = (points[..., channels] - self.unit_shift[:, channels]) / self.unit_scale[list(channels)]
        return torch.logit(unit.clamp(1e-4, 1 - 1e-4))

    def normalise(self, points: Tensor) -> Tensor:
        """Points (..., 4) = (x, y, z, v) in metres -> each coordinate mapped by its range to
        [0, 1] (v as is), the input of the positional encoding. Propagated memory points may
        fall outside [0, 1]."""
        return normalise_points(points, self.normaliser)

    def classify(self, queries: Tensor) -> Tensor:
        """queries (B, N, M, C) -> class logits (B, N, K + 1), background last."""
        return self.class_mlp(queries.mean(dim=-2))

    def decode(self, points: Tensor, y: Tensor) -> Tensor:
        """Control points (..., M, 4) -> dense lanes (..., S, 4) = (x, y, z, v) at y (S,) in
        y_range. Computed in the points' precision, also under autocast."""
        with torch.autocast(points.device.type, enabled=False):
            dense = self.curves.sample(points, y.to(points))
        x, _, z, v = dense.unbind(-1)
        return torch.stack([x, y.to(points).expand_as(x), z, v], dim=-1)
