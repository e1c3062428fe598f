"""SparseLaneSTP's training objective: matching, detection losses, priors, deep supervision.

For every decoder layer (deep supervision, as DETR / LATR: each layer matched on its own):
the predicted curves are sampled at the ground truth's y grid (curve arguments eq. 21), the
Hungarian matcher pairs proposals with lanes, and the detection losses follow (eq. 22-24;
unmatched proposals are background). The spatial priors act on the matched lines of every
layer, the temporal prior on ``outputs["temporal"]`` (the current prediction and the memory).
Noised ground-truth lanes (query denoising, models.sparselanestp.query_denoising) are their own lanes' targets
without matching; their "denoise" term is their cls + reg + vis, weighted as the matched lines'.
Every term is summed over layers and weighted by ``weights``; terms of weight 0 are skipped.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import Tensor, nn

from lanelab.geometry.curves import LaneCurves, sample_lanes
from lanelab.models.categories import category_to_index
from lanelab.models.parts.detection_losses import focal_loss, regression_loss, visibility_loss
from lanelab.models.parts.matcher import HungarianMatcher
from lanelab.models.sparselanestp.priors import curvature_excess, parallelism_and_surface, temporal_consistency

TERMS = ("cls", "reg", "vis", "parallel", "surface", "curvature", "temporal", "denoise")


class SparseLaneSTPLoss(nn.Module):
    """matcher: a HungarianMatcher; weights: {term: weight} over TERMS (missing: 0);
    y_range: (y_s, y_e) of the control points; num_control_points M; gamma: focal parameter;
    representation: "catmull_rom" or "discrete" (LATR's points, linear in between);
    max_curvature: κ_max (1/m) of the curvature prior; temporal_alpha: α of eq. 13;
    temporal_max_distance: mean L1 distance (m) within which a past line is the same lane."""

    def __init__(
        self,
        matcher: HungarianMatcher,
        weights: Mapping[str, float],
        *,
        y_range: tuple[float, float],
        num_control_points: int,
        gamma: float,
        representation: str,
        max_curvature: float,
        temporal_alpha: float,
        temporal_max_distance: float,
    ) -> None:
        super().__init__()
        unknown = set(weights) - set(TERMS)
        if unknown:
            raise ValueError(f"unknown loss terms {sorted(unknown)}; known: {TERMS}")
        self.matcher = matcher
        self.weights = {term: float(weights.get(term, 0.0)) for term in TERMS}
        self.curves = LaneCurves(representation, num_control_points, tuple(y_range))
        self.gamma = gamma
        self.max_curvature = max_curvature
        self.temporal_alpha, self.temporal_max_distance = temporal_alpha, temporal_max_distance

    def forward(self, outputs: Mapping, targets: Mapping[str, Tensor]) -> dict[str, Tensor]:
        """outputs: {"layers": [{"control_points": (B, N, M, 4), "logits": (B, N, K + 1)}, ...],
        optionally "temporal": {"current": (B, N, M, 4), "propagated_memory": MemoryState | None},
        "anchors": the lines' lateral anchors (N,) (for HungarianMatcher(match_on="anchors")) and
        "denoising": {"points": (L, B, R G, M, 4), "logits": (L, B, R G, K + 1)}, R noised copies
        of the G lanes (line r G + g is lane g's);
        targets: the collated dataset batch: gt_y (S,) or (B, S), gt_x / gt_z / gt_vis (B, G, S),
        gt_category (B, G) OpenLane ids, gt_mask (B, G).
        Returns every term of TERMS (summed over layers), "total", the weighted sum, and
        "matches": the last layer's (line index, lane index) pairs per image, for auxiliary
        losses that must pair lines and lanes alike (the instance masks)."""
        first = outputs["layers"][0]["control_points"]
        losses = {term: first.new_zeros(()) for term in TERMS}
        bases = self.curves.bases(targets["gt_y"].to(first))  # (S, M) or (B, S, M) each
        anchors = outputs.get("anchors")
        for layer in outputs["layers"]:
            layer_losses, matches = self._layer_losses(layer["control_points"], layer["logits"], bases, targets, anchors)
            for term, value in layer_losses.items():
                losses[term] = losses[term] + value
        if self.weights["temporal"] and "temporal" in outputs:
            temporal = outputs["temporal"]
            losses["temporal"] = temporal_consistency(
                temporal["current"], temporal["propagated_memory"], self.temporal_alpha, self.temporal_max_distance
            )
        if self.weights["denoise"] and outputs.get("denoising") is not None:
            losses["denoise"] = self._denoising_loss(outputs["denoising"], bases, targets)
        losses["total"] = sum(self.weights[term] * losses[term] for term in TERMS)
        return {**losses, "matches": matches}

    def _denoising_loss(
        self, denoising: Mapping[str, Tensor], bases: tuple[Tensor, Tensor], targets: Mapping[str, Tensor]
    ) -> Tensor:
        """The noised lanes' detection losses against the lanes they were made from, summed over
        layers, each term weighted as the matched lines' are."""
        copies = denoising["points"].shape[2] // targets["gt_mask"].shape[1]
        mask = targets["gt_mask"].repeat(1, copies)
        gt_x, gt_z, gt_vis = (
            targets[key].repeat(1, copies, 1)[mask].to(denoising["points"]) for key in ("gt_x", "gt_z", "gt_vis")
        )
        target = category_to_index(targets["gt_category"].repeat(1, copies)[mask])
        total = denoising["points"].new_zeros(())
        for points, logits in zip(denoising["points"], denoising["logits"]):
            curves = sample_lanes(points, bases)[mask]  # (P, S, 4)
            terms = self._detection_terms(logits[mask], target, curves, gt_x, gt_z, gt_vis)
            total = total + sum(self.weights[term] * value for term, value in terms.items())
        return total

    def _detection_terms(
        self, logits: Tensor, target: Tensor, curves: Tensor, gt_x: Tensor, gt_z: Tensor, gt_vis: Tensor
    ) -> dict[str, Tensor]:
        """Eq. 22-24: "cls" of logits (..., K + 1) against their class indices (...); "reg" and
        "vis" of the curves (P, S, 4) paired with the lanes' samples gt_x, gt_z, gt_vis (P, S)."""
        return {
            "cls": focal_loss(logits, target, self.gamma),
            "reg": regression_loss(curves, gt_x, gt_z, gt_vis, gt_vis.sum().clamp(min=1)),
            "vis": visibility_loss(curves, gt_vis, max(gt_vis.numel(), 1)),
        }

    def _layer_losses(
        self, points: Tensor, logits: Tensor, bases: tuple[Tensor, Tensor], targets: Mapping[str, Tensor],
        anchors: Tensor | None,
    ) -> tuple[dict[str, Tensor], list[tuple[Tensor, Tensor]]]:  # fmt: skip
        """Matching, detection losses and spatial priors of one decoder layer's output, and its matches."""
        B, N = logits.shape[:2]
        curves = sample_lanes(points, bases)  # (B, N, S, 4)
        matches = self.matcher(logits, curves, targets, anchors)
        batch = torch.cat([torch.full_like(pred, b) for b, (pred, _) in enumerate(matches)])
        pred = torch.cat([pred for pred, _ in matches])
        gt = torch.cat([gt for _, gt in matches])

        target = torch.full((B, N), logits.shape[-1] - 1, dtype=torch.long, device=logits.device)  # background
        target[batch, pred] = category_to_index(targets["gt_category"][batch, gt])
        matched = curves[batch, pred]  # (P, S, 4)
        gt_x, gt_z, gt_vis = (targets[key][batch, gt].to(curves) for key in ("gt_x", "gt_z", "gt_vis"))
        losses = self._detection_terms(logits, target, matched, gt_x, gt_z, gt_vis)
        lines = torch.zeros(B, N, dtype=torch.bool, device=logits.device)
        lines[batch, pred] = True
        if self.weights["parallel"] or self.weights["surface"]:
            losses["parallel"], losses["surface"] = parallelism_and_surface(points, lines)
        if self.weights["curvature"]:
            losses["curvature"] = curvature_excess(points, lines, self.max_curvature)
        return losses, matches
