"""Hungarian matching of line proposals to ground-truth lanes (DETR's set prediction).

The pair cost mirrors the losses, as DETR / LATR do, each term normalised per lane so that
long and short lanes weigh alike:
- class: the focal loss (SparseLaneSTP eq. 22) the proposal would pay for the lane's category,
  -(1 - p)^γ log p with p the softmax probability (γ = 0: cross-entropy);
- reg: mean L1 distance |x - x̂| + |z - ẑ| over the lane's visible ground-truth samples (eq. 23);
- vis: mean |v - v̂| over all samples (eq. 24's target, as an L1 cost; bounded, unlike BCE).
Targets are the collated dataset batch (lanelab.data): ``gt_x``, ``gt_z``, ``gt_vis`` (B, G, S)
at the grid ``gt_y``, ``gt_category`` (B, G) OpenLane ids, ``gt_mask`` (B, G) real lanes.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from scipy.optimize import linear_sum_assignment
from torch import Tensor, nn

from lanelab.models.heads import category_to_index


class HungarianMatcher(nn.Module):
    """cost_class, cost_reg, cost_vis: weights of the three pair costs; gamma: focal parameter."""

    def __init__(self, cost_class: float = 1.0, cost_reg: float = 1.0, cost_vis: float = 1.0, gamma: float = 2.0):
        super().__init__()
        self.cost_class, self.cost_reg, self.cost_vis, self.gamma = cost_class, cost_reg, cost_vis, gamma

    @torch.no_grad()
    def forward(
        self, pred_logits: Tensor, pred_curves: Tensor, targets: Mapping[str, Tensor]
    ) -> list[tuple[Tensor, Tensor]]:
        """pred_logits (B, N, K + 1), background last; pred_curves (B, N, S, 4) = (x, y, z, v)
        sampled at the ground truth's y grid. Returns per batch item (pred_index, gt_index),
        long tensors of equal length min(N, G_b), gt_index into the padded G axis."""
        cost = self.cost_matrix(pred_logits, pred_curves, targets).cpu()
        matches = []
        for cost_b, real in zip(cost, targets["gt_mask"].cpu()):  # the solver is per image
            gt_index = real.nonzero()[:, 0]
            rows, cols = linear_sum_assignment(cost_b[:, gt_index].numpy())
            matches.append((torch.as_tensor(rows, dtype=torch.long), gt_index[torch.as_tensor(cols, dtype=torch.long)]))
        device = pred_logits.device
        return [(pred.to(device), gt.to(device)) for pred, gt in matches]

    def cost_matrix(self, pred_logits: Tensor, pred_curves: Tensor, targets: Mapping[str, Tensor]) -> Tensor:
        """Pair costs (B, N, G) of every proposal and every (padded) ground-truth lane."""
        B, N = pred_logits.shape[:2]
        G = targets["gt_mask"].shape[1]
        classes = category_to_index(targets["gt_category"])  # (B, G)
        log_p = pred_logits.float().log_softmax(-1).gather(2, classes[:, None, :].expand(B, N, G))
        cost_class = -((1 - log_p.exp()) ** self.gamma) * log_p

        visible = targets["gt_vis"][:, None].float()  # (B, 1, G, S)
        x, _, z, v = pred_curves.float()[:, :, None].unbind(-1)  # (B, N, 1, S)
        distance = (x - targets["gt_x"][:, None]).abs() + (z - targets["gt_z"][:, None]).abs()
        cost_reg = (distance * visible).sum(-1) / visible.sum(-1).clamp_min(1)
        cost_vis = (v.clamp(0, 1) - visible).abs().mean(-1)
        return self.cost_class * cost_class + self.cost_reg * cost_reg + self.cost_vis * cost_vis
