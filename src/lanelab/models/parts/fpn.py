"""Feature pyramid network (Lin et al. 2017), the neck between backbone and decoder.

Configured as LATR's neck (mmdet FPN on C3..C5, add_extra_convs="on_output",
relu_before_extra_convs): lateral 1x1 convolutions, a top-down pathway with nearest
upsampling, 3x3 output convolutions, and extra stride-2 levels on top of the last output.
With fewer output levels than inputs, the coarser inputs still feed the top-down pathway.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch.nn.functional as F
from torch import Tensor, nn


class FPN(nn.Module):
    """in_channels: channels of the backbone maps (finest first); out_channels: C of every
    level; num_levels: output levels (LATR: 4 on C3..C5, strides 8, 16, 32 and an extra 64)."""

    def __init__(self, in_channels: Sequence[int], out_channels: int, num_levels: int) -> None:
        super().__init__()
        num_outputs = min(num_levels, len(in_channels))
        self.lateral = nn.ModuleList(nn.Conv2d(c, out_channels, 1) for c in in_channels)
        self.output = nn.ModuleList(nn.Conv2d(out_channels, out_channels, 3, padding=1) for _ in range(num_outputs))
        self.extra = nn.ModuleList(
            nn.Conv2d(out_channels, out_channels, 3, stride=2, padding=1) for _ in range(num_levels - num_outputs)
        )

    def forward(self, features: Sequence[Tensor]) -> list[Tensor]:
        """features [(B, in_channels[i], H_i, W_i)], finest first -> num_levels maps
        [(B, out_channels, H_l, W_l)], finest first, each half the size of the previous."""
        laterals = [conv(x) for conv, x in zip(self.lateral, features, strict=True)]
        for i in range(len(laterals) - 1, 0, -1):
            laterals[i - 1] = laterals[i - 1] + F.interpolate(laterals[i], size=laterals[i - 1].shape[-2:])
        outputs = [conv(x) for conv, x in zip(self.output, laterals)]
        for conv in self.extra:
            outputs.append(conv(F.relu(outputs[-1])))
        return outputs
