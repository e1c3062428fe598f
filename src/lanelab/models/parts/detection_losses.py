"""Detection losses of SparseLaneSTP, supplementary B (eq. 22-24), shared with Bi²Lane's criterion
(:mod:`lanelab.models.bi2lane.criterion`: its classification, eq. 12, and regression, eq. 13).

The classification is a mean over the N proposals of every image (eq. 22). Eq. 23-24 are sums
over the matched lines' ground-truth samples; the paper divides them by N, which makes their
scale grow with the number and length of the lanes in a batch (a frame with eight long lanes
weighs eight times one with a short one). As LATR does, they are divided by the count they sum
over instead: ``normaliser`` = the visible samples for eq. 23, all samples for eq. 24, so both
are per-sample means (metres, nats) whatever the batch holds.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor

# Visibility probabilities are clamped into [eps, 1 - eps] for the BCE: the Catmull-Rom curve
# through visibilities in (0, 1) can overshoot between control points.
VISIBILITY_EPS = 1e-4


def focal_loss(logits: Tensor, target: Tensor, gamma: float) -> Tensor:
    """Eq. 22: -1/N Σ_i Σ_k Ĉ_ik (1 - C_ik)^γ log C_ik with C = softmax over K + 1 classes.

    logits (B, N, K + 1); target (B, N) class indices (background = K for unmatched proposals).
    Returns the mean over proposals and images."""
    log_p = logits.log_softmax(-1).gather(-1, target[..., None])[..., 0]
    return -((1 - log_p.exp()) ** gamma * log_p).mean()


def regression_loss(curves: Tensor, gt_x: Tensor, gt_z: Tensor, gt_vis: Tensor, normaliser: int | Tensor) -> Tensor:
    """Eq. 23: Σ v̂ (|f_x(ŝ) - x̂| + |f_z(ŝ) - ẑ|) over matched lines and their ground-truth
    samples; curves (P, S, 4) the P matched predictions at the samples' curve arguments,
    gt_x, gt_z, gt_vis (P, S)."""
    distance = (curves[..., 0] - gt_x).abs() + (curves[..., 2] - gt_z).abs()
    return (distance * gt_vis).sum() / normaliser


def visibility_loss(curves: Tensor, gt_vis: Tensor, normaliser: int | Tensor) -> Tensor:
    """Eq. 24 (printed without the minus sign of a cross-entropy): binary cross-entropy of the
    predicted visibility f_v at every ground-truth sample of the matched lines, (P, S).
    In float32 outside autocast, which refuses a cross-entropy of probabilities (f_v is an
    interpolation of them, not a sigmoid of one logit)."""
    probability = curves[..., 3].float().clamp(VISIBILITY_EPS, 1 - VISIBILITY_EPS)
    with torch.autocast(curves.device.type, enabled=False):
        return F.binary_cross_entropy(probability, gt_vis.float(), reduction="sum") / normaliser
