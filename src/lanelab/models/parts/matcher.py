"""Hungarian matching of line proposals to ground-truth lanes (DETR's set prediction).

The pair cost mirrors the losses, as DETR / LATR do, each term normalised per lane so that
long and short lanes weigh alike:
- class: the focal loss (SparseLaneSTP eq. 22) the proposal would pay for the lane's category,
  -(1 - p)^γ log p with p the softmax probability (γ = 0: cross-entropy);
- reg: mean L1 distance |x - x̂| + |z - ẑ| over the lane's visible ground-truth samples (eq. 23);
- vis: mean |v - v̂| over all samples (eq. 24's target, as an L1 cost; bounded, unlike BCE).
Targets are the collated dataset batch (lanelab.data): ``gt_x``, ``gt_z``, ``gt_vis`` (B, G, S)
at the grid ``gt_y``, ``gt_category`` (B, G) OpenLane ids, ``gt_mask`` (B, G) real lanes.

``match_on="anchors"`` (with a model that has line anchors, see models.sparselanestp.query_init) pairs lanes
with lines by where the lines start, not by what they predict, as Anchor3DLane assigns lanes to
its anchors: the cost is the mean |x̂ - a| between the line's lateral anchor a and the lane's
visible samples nearer than ``near_range`` m (all visible samples for a lane that starts
further away). Models with 3D anchors (Bi²Lane's, models.bi2lane.anchors) give each anchor's
(x, z) at the ground truth's samples instead, and the distance is Anchor3DLane's Euclidean one,
sqrt((x̂ - a_x)² + (ẑ - a_z)²), averaged over the same samples. Matching on predictions is DETR's way and needs good predictions to be stable;
early in training they are not, a lane goes to a different line from step to step, and every
line learns the mean lane layout. Matching on anchors gives each line the same lane every step.
With ``max_anchor_distance`` (Anchor3DLane's positive threshold) a pair whose anchor cost exceeds
it is dropped: the lane is then no line's target, and the line is background. Without it every
lane goes to some line however far, and a line's targets jump between lanes metres apart, which
teaches it the median of its neighbourhood and a class that says nothing about the image.
With ``positive_distance`` the assignment is Anchor3DLane's one-to-many instead of Hungarian:
every line whose anchor lies within that distance of a lane learns it (each line the nearest
such lane), and a lane with none that near gets its nearest free line within
``max_anchor_distance``. Neighbouring lines then learn the same lane rather than one of them
being taught it is background while it sees the same image; the duplicates are removed at
inference (models.parts.lane_nms). Measured on the demo's drives (issue "The detectors must learn"):
validation F1 after 500 steps 38 % against 10 % with Hungarian anchor matching.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from scipy.optimize import linear_sum_assignment
from torch import Tensor, nn

from lanelab.models.categories import category_to_index

MATCH_ON = ("predictions", "anchors")


class HungarianMatcher(nn.Module):
    """cost_class, cost_reg, cost_vis: weights of the three pair costs; gamma: focal parameter;
    match_on: "predictions" (DETR) or "anchors" (the lines' lateral anchors, module doc);
    near_range: metres of the anchor cost; max_anchor_distance: metres of anchor cost above which
    a pair is dropped (match_on="anchors"), None: keep every pair; positive_distance: metres of
    anchor cost within which every line learns the lane (one-to-many, module doc), None: one
    line per lane."""

    def __init__(
        self,
        cost_class: float,
        cost_reg: float,
        cost_vis: float,
        gamma: float,
        match_on: str,
        near_range: float,
        max_anchor_distance: float | None,
        positive_distance: float | None,
    ) -> None:
        super().__init__()
        if match_on not in MATCH_ON:
            raise ValueError(f"match_on must be one of {MATCH_ON}, got {match_on!r}")
        for name, value in (("max_anchor_distance", max_anchor_distance), ("positive_distance", positive_distance)):
            if value is not None and match_on != "anchors":
                raise ValueError(f'{name} needs match_on="anchors" (got {match_on!r}); set it to null')
        self.cost_class, self.cost_reg, self.cost_vis, self.gamma = cost_class, cost_reg, cost_vis, gamma
        self.match_on, self.near_range = match_on, near_range
        self.max_anchor_distance = max_anchor_distance
        self.positive_distance = positive_distance

    @torch.no_grad()
    def forward(
        self, pred_logits: Tensor, pred_curves: Tensor, targets: Mapping[str, Tensor], anchors: Tensor | None = None
    ) -> list[tuple[Tensor, Tensor]]:
        """pred_logits (B, N, K + 1), background last; pred_curves (B, N, S, 4) = (x, y, z, v)
        sampled at the ground truth's y grid; anchors, needed by match_on="anchors": lateral
        anchors (N,) or 3D anchors' (x, z) at the ground truth's y grid (B, N, S, 2), metres.
        Returns per batch item (pred_index, gt_index), long tensors of equal length (min(N, G_b)
        without positive_distance; a lane may have several lines with it), gt_index into the
        padded G axis."""
        if self.match_on == "anchors":
            if anchors is None:
                raise ValueError('match_on="anchors" needs a model with line anchors (model.net.anchor_span)')
            cost = self.anchor_cost(anchors, targets).cpu()
        else:
            cost = self.cost_matrix(pred_logits, pred_curves, targets).cpu()
        matches = []
        for cost_b, real in zip(cost, targets["gt_mask"].cpu()):  # the solver is per image
            gt_index = real.nonzero()[:, 0]
            if self.positive_distance is not None and len(gt_index):
                matches.append(self._one_to_many(cost_b[:, gt_index], gt_index))
                continue
            rows, cols = linear_sum_assignment(cost_b[:, gt_index].numpy())
            if self.max_anchor_distance is not None:
                close = cost_b[rows, gt_index[cols]].numpy() <= self.max_anchor_distance
                rows, cols = rows[close], cols[close]
            matches.append((torch.as_tensor(rows, dtype=torch.long), gt_index[torch.as_tensor(cols, dtype=torch.long)]))
        device = pred_logits.device
        return [(pred.to(device), gt.to(device)) for pred, gt in matches]

    def anchor_cost(self, anchors: Tensor, targets: Mapping[str, Tensor]) -> Tensor:
        """Pair costs (B, N, G) of lateral anchors (N,) or 3D anchors (B, N, S, 2) (module doc):
        their mean distance from each lane over its near visible samples."""
        visible = targets["gt_vis"] > 0.5  # (B, G, S)
        y = targets["gt_y"] if targets["gt_y"].dim() == 2 else targets["gt_y"].expand(visible.shape[0], -1)
        near = visible & (y[:, None, :] <= self.near_range)
        used = torch.where(near.any(-1, keepdim=True), near, visible).float()[:, None]  # (B, 1, G, S)
        if anchors.dim() == 1:
            distance = (targets["gt_x"][:, None].float() - anchors.float()[None, :, None, None]).abs()  # (B, N, G, S)
        else:
            a_x, a_z = anchors.float()[:, :, None].unbind(-1)  # (B, N, 1, S)
            distance = torch.hypot(targets["gt_x"][:, None].float() - a_x, targets["gt_z"][:, None].float() - a_z)
        return (distance * used).sum(-1) / used.sum(-1).clamp_min(1)

    def _one_to_many(self, cost: Tensor, gt_index: Tensor) -> tuple[Tensor, Tensor]:
        """Anchor3DLane's assignment: every line whose anchor lies within positive_distance of a
        lane is that lane's (the nearest lane's, where several are that close); a lane with no
        such line gets its nearest free one within max_anchor_distance. cost (N, G)."""
        nearest_cost, nearest = cost.min(-1)
        rows = (nearest_cost <= self.positive_distance).nonzero()[:, 0]
        cols = nearest[rows]
        free = torch.ones(cost.shape[0], dtype=torch.bool)
        free[rows] = False
        for g in sorted(set(range(cost.shape[1])) - set(cols.tolist())):
            if not free.any():
                break
            candidates = torch.where(free, cost[:, g], torch.inf)
            line = int(candidates.argmin())
            if self.max_anchor_distance is None or candidates[line] <= self.max_anchor_distance:
                rows, cols = torch.cat([rows, rows.new_tensor([line])]), torch.cat([cols, cols.new_tensor([g])])
                free[line] = False
        return rows.long(), gt_index[cols]

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
