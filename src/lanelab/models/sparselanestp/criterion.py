"""SparseLaneSTP's criterion: its training loss as the Lightning module calls it, with the model's
outputs (``SparseLaneSTP.forward`` / ``step``) and the batch (:class:`~lanelab.models.api.LaneCriterion`).

On the frames that count (:func:`~lanelab.models.api.scored_frames`): the detection loss
(:class:`~lanelab.models.sparselanestp.SparseLaneSTPLoss`: detection losses with deep supervision over
all decoder layers, spatial priors, the temporal regulariser of eq. 12-13 against the memory
each frame attended to) plus the query generator's auxiliary instance-mask loss
(:class:`~lanelab.models.sparselanestp.InstanceMaskLoss`), which pairs each line's mask with the lane
the detection loss gave that line (as LATR trains both on one assignment); with a lateral-offset
map (models.sparselanestp.lateral_offset), its dense loss (:class:`~lanelab.models.sparselanestp.LateralOffsetLoss`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from torch import Tensor, nn

from lanelab.models.api import TARGET_KEYS, scored_frames
from lanelab.models.sparselanestp.deep_supervision import SparseLaneSTPLoss
from lanelab.models.sparselanestp.instance_mask_loss import InstanceMaskLoss
from lanelab.models.sparselanestp.lateral_offset_loss import LateralOffsetLoss


def detection_inputs(outputs: Mapping[str, Any], frames: Tensor) -> dict[str, Any]:
    """SparseLaneSTPLoss's input for the batch elements selected by frames (B,) bool: every
    decoder layer's control points (B', N, M, 4) and logits (B', N, K + 1), and for the
    temporal regulariser the last layer's points with the memory the frame attended to; the
    lines' anchors (the matcher's, when it matches on anchors); the noised lanes' outputs, where
    the model decoded some (query denoising)."""
    points, logits = outputs["points"][:, frames], outputs["logits"][:, frames]
    memory = outputs["memory"]
    if memory is not None:
        memory = memory.map(lambda tensor: tensor[frames])
    denoising = outputs.get("denoising")
    if denoising is not None:
        denoising = {key: value[:, frames] for key, value in denoising.items()}
    return {
        "layers": [{"control_points": p, "logits": c} for p, c in zip(points, logits)],
        "temporal": {"current": points[-1], "propagated_memory": memory},
        "anchors": outputs.get("anchors"),
        "denoising": denoising,
    }


class SparseLaneSTPCriterion(nn.Module):
    """detection: the SparseLaneSTPLoss; instance_mask: the InstanceMaskLoss of the query generator;
    lateral_offset: the LateralOffsetLoss of the model's lateral-offset map, or None (the model has
    none)."""

    def __init__(
        self, detection: SparseLaneSTPLoss, instance_mask: InstanceMaskLoss, lateral_offset: LateralOffsetLoss | None = None
    ) -> None:
        super().__init__()
        self.detection, self.instance_mask, self.lateral_offset = detection, instance_mask, lateral_offset

    def forward(self, outputs: Mapping[str, Any], batch: Mapping[str, Any]) -> dict[str, Tensor]:
        """outputs: SparseLaneSTP's (points (L, B, N, M, 4), logits (L, B, N, K + 1), masks
        (B, N, h, w), anchors, memory); batch: the collated batch (lanelab.models.api).
        Returns "total", the detection terms of non-zero weight (summed over layers; "denoise"
        only with noised lanes in the outputs) and the
        instance masks' "mask_dice" and "mask_bce", the lateral-offset map's "offset" and
        "offset_confidence" (with one); only "total" where no frame counts."""
        scored = scored_frames(batch)
        if not bool(scored.any()):
            # Nothing to learn from; a zero that reaches the outputs keeps DDP ranks in step.
            used = [outputs[key] for key in ("points", "logits", "masks", "offsets") if outputs.get(key) is not None]
            used += list((outputs.get("denoising") or {}).values())
            return {"total": sum(tensor.sum() * 0.0 for tensor in used)}
        targets = {key: batch[key][scored] for key in TARGET_KEYS}
        losses = self.detection(detection_inputs(outputs, scored), targets)
        camera = batch["K"][scored, -1], batch["T_lane_cam"][scored, -1]
        # Each line's instance mask is the lane its control points are trained on (LATR pairs both alike).
        masks = self.instance_mask(
            outputs["masks"][scored], targets, *camera, tuple(batch["images"].shape[-2:]), losses["matches"]
        )
        # "denoise" only where the model decoded noised lanes (query denoising, in training)
        denoised = outputs.get("denoising") is not None
        weights = self.detection.weights
        terms = {term: losses[term] for term, weight in weights.items() if weight and (denoised or term != "denoise")}
        terms.update(mask_dice=masks["dice"], mask_bce=masks["bce"])
        total = losses["total"] + masks["total"]
        if self.lateral_offset is not None:
            if outputs.get("offsets") is None:
                raise ValueError("the criterion has a lateral_offset loss but the model makes no lateral-offset map")
            read = self.lateral_offset(outputs["offsets"][scored], targets, *camera, tuple(batch["images"].shape[-2:]))
            terms.update(offset=read["offset"], offset_confidence=read["confidence"])
            total = total + read["total"]
        return {"total": total, **terms}
