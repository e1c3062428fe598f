"""Lane-aware query generator: the query initialisation of SparseLaneSTP §3.2, "similar to [33]".

The paper defers to LATR, whose generator is SparseInst's instance branch (Cheng et al. 2022):
convolutions over an image feature map (plus two coordinate channels) predict N instance
activation maps; each line embedding is the feature map averaged under its map. A mask
branch turns the same line embeddings into kernels for N instance masks, trained by the
auxiliary lane instance-segmentation loss, which is what makes the embeddings lane-aware.
As in LATR, line and point embeddings combine by broadcast addition into N x M queries
(0Q of §3.2), and an MLP predicts the initial control points 0P from them.

Simplifications of LATR's version (where the paper is silent): one activation map per line
(LATR uses SparseInst's 4-group maps) and no class/objectness outputs on the instance branch
(the decoder's classifier does that job).

Line anchors (optional; DAB-DETR's learned anchors, Anchor3DLane's lateral anchors): each line
starts from its own learned lateral offset, spread evenly over [-anchor_span, anchor_span] m,
and the MLP predicts the initial points as corrections of that straight line (its last layer
starts at zero). Without them every line starts from the same place and only the matcher tells
them apart; with them a line has a place on the road from the first step, and the matcher can
assign lanes by it (``HungarianMatcher(match_on="anchors")``).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from lanelab.models.parts.heads import mlp


def _conv_stack(in_channels: int, channels: int, num_convs: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i in range(num_convs):
        layers += [nn.Conv2d(in_channels if i == 0 else channels, channels, 3, padding=1), nn.ReLU(inplace=True)]
    return nn.Sequential(*layers)


def _with_coordinates(features: Tensor) -> Tensor:
    """Append normalised x, y coordinate channels in [-1, 1] (SparseInst, CoordConv)."""
    B, _, H, W = features.shape
    y = torch.linspace(-1, 1, H, dtype=features.dtype, device=features.device)
    x = torch.linspace(-1, 1, W, dtype=features.dtype, device=features.device)
    grid_y, grid_x = torch.meshgrid(y, x, indexing="ij")
    coordinates = torch.stack([grid_x, grid_y]).expand(B, 2, H, W)
    return torch.cat([features, coordinates], dim=1)


class LaneQueryGenerator(nn.Module):
    """embed_dim C: channels of the feature map and of the queries; num_lines N;
    num_points M; num_convs: 3x3 convolutions per branch (LATR: 4); mask_dim: channels of the
    mask features and kernels; num_hidden: hidden layers of the control point MLP;
    anchor_logits: (N,) initial pre-sigmoid x of the line anchors, or None (no anchors)."""

    def __init__(
        self,
        embed_dim: int,
        num_lines: int,
        num_points: int,
        num_convs: int,
        mask_dim: int,
        num_hidden: int,
        anchor_logits: Tensor | None = None,
    ) -> None:
        super().__init__()
        self.instance_convs = _conv_stack(embed_dim + 2, embed_dim, num_convs)
        self.activation_maps = nn.Conv2d(embed_dim, num_lines, 3, padding=1)
        self.line_proj = nn.Linear(embed_dim, embed_dim)
        self.mask_kernel = nn.Linear(embed_dim, mask_dim)
        self.mask_convs = nn.Sequential(
            _conv_stack(embed_dim + 2, embed_dim, num_convs), nn.Conv2d(embed_dim, mask_dim, 1)
        )
        self.point_embedding = nn.Embedding(num_points, embed_dim)
        self.initial_points = mlp(embed_dim, embed_dim, 3, num_hidden)
        # SparseInst: activation maps start near-uniform and small (prior probability 0.01),
        # so every line embedding first sees the mean feature.
        nn.init.normal_(self.activation_maps.weight, std=0.01)
        nn.init.constant_(self.activation_maps.bias, -math.log((1 - 0.01) / 0.01))
        self.anchor_logits = None if anchor_logits is None else nn.Parameter(anchor_logits.clone().float())
        if self.anchor_logits is not None:  # start exactly on the anchors
            nn.init.zeros_(self.initial_points[-1].weight)
            nn.init.zeros_(self.initial_points[-1].bias)

    def forward(self, features: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """features (B, C, H, W), LATR: the stride-8 FPN level.

        Returns queries 0Q (B, N, M, C), initial control point logits (B, N, M, 3) (pre-sigmoid
        x, z, v; see LaneHead.control_points) and instance-mask logits (B, N, H, W).
        """
        B, C, H, W = features.shape
        features = _with_coordinates(features)
        instance = self.instance_convs(features)
        activation = self.activation_maps(instance).sigmoid().flatten(2)  # (B, N, H W)
        activation = activation / activation.sum(-1, keepdim=True).clamp(min=1e-6)
        lines = self.line_proj(activation @ instance.flatten(2).transpose(1, 2))  # (B, N, C)

        mask_features = self.mask_convs(features).flatten(2)  # (B, D, H W)
        masks = (self.mask_kernel(lines) @ mask_features).view(B, -1, H, W)

        queries = lines[:, :, None, :] + self.point_embedding.weight  # (B, N, M, C)
        logits = self.initial_points(queries)
        if self.anchor_logits is not None:
            logits = torch.cat([logits[..., :1] + self.anchor_logits[:, None, None], logits[..., 1:]], -1)
        return queries, logits, masks
