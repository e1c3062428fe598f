"""The auxiliary BEV segmentation branch of Bi²Lane (§III-D: "a separate BEV segmentation loss ...
where the BEV feature is transformed from FV feature").

The paper names no more; as PersFormer (its source for this branch), the front-view feature map
is carried onto a ground grid by inverse perspective mapping (every cell's point on the ground
plane z = 0 projected into the image, the feature there sampled; PersFormer starts its
perspective transformer from this mapping), and a small convolutional head predicts a lane
mask there. Only training reads it: it shapes the shared features, the detection does not use it.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from lanelab.models.bi2lane.anchors import sample_features, sampling_grid


class BEVSegmentation(nn.Module):
    """in_channels C of the front-view features; x_range, y_range (metres, lane frame): the
    ground region; size (rows, columns) of its grid (row 0 nearest, column 0 leftmost);
    hidden channels of the head's two 3x3 convolutions."""

    def __init__(
        self, in_channels: int, x_range: Sequence[float], y_range: Sequence[float], size: Sequence[int], hidden: int
    ) -> None:
        super().__init__()
        rows, columns = size
        (x0, x1), (y0, y1) = x_range, y_range
        # Cell centres: the grid covers the region edge to edge.
        self.register_buffer("x", x0 + (torch.arange(columns) + 0.5) * (x1 - x0) / columns, persistent=False)
        self.register_buffer("y", y0 + (torch.arange(rows) + 0.5) * (y1 - y0) / rows, persistent=False)
        self.head = nn.Sequential(
            nn.Conv2d(in_channels, hidden, 3, padding=1), nn.ReLU(inplace=True),
            nn.Conv2d(hidden, hidden, 3, padding=1), nn.ReLU(inplace=True),
            nn.Conv2d(hidden, 1, 1),
        )  # fmt: skip

    def ground_points(self) -> Tensor:
        """The cells' centres on the ground (rows, columns, 3), lane frame."""
        y, x = torch.meshgrid(self.y, self.x, indexing="ij")
        return torch.stack([x, y, torch.zeros_like(x)], dim=-1)

    def forward(self, features: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]) -> Tensor:
        """features (B, C, h, w) covering images of image_size (H, W), seen by K (B, 3, 3),
        T_lane_cam (B, 4, 4) -> lane-mask logits (B, rows, columns)."""
        points = self.ground_points().to(features.dtype).expand(features.shape[0], -1, -1, -1)
        bev = sample_features(features, sampling_grid(points, K, T_lane_cam, image_size))  # (B, rows, columns, C)
        return self.head(bev.permute(0, 3, 1, 2))[:, 0]
