"""A criterion whose loss is NaN on rank 1 from its second step on: a fault that one DDP process
sees and the other does not (a test helper, importable by the spawned processes)."""

from __future__ import annotations

import math

import torch.distributed as dist

from lanelab.models.sparselanestp import SparseLaneSTPCriterion


class NaNOnRankOne(SparseLaneSTPCriterion):
    calls = 0

    def forward(self, outputs, batch):
        losses = super().forward(outputs, batch)
        if self.training:
            NaNOnRankOne.calls += 1
        if self.training and dist.is_initialized() and dist.get_rank() == 1 and NaNOnRankOne.calls >= 2:
            return {**losses, "total": losses["total"] * math.nan}
        return losses
