"""Optimisers and learning-rate schedules, as the optimizer and scheduler groups of conf/ build them
(Hydra partials, which :class:`~lanelab.lightning.LaneDetectionModule` calls).

LATR's (config/release_iccv/latr_1000_baseline.py), which SparseLaneSTP (§5.2) trains with: AdamW,
lr 2e-4, weight decay 0.01, the deformable attention's sampling offsets at 0.1 x lr (mmcv
``custom_keys``), a cosine schedule down to 1e-5. Here the schedule runs per optimiser step over
the whole training run, after a linear warm-up, and any parameter-name key (e.g. "backbone") can
get its own multiplier.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import torch
from torch import nn
from torch.optim import Optimizer
from torch.optim.lr_scheduler import LambdaLR


def parameter_groups(module: nn.Module, lr: float, lr_multipliers: Mapping[str, float]) -> list[dict]:
    """Optimiser parameter groups: one per key of lr_multipliers, holding the trainable
    parameters whose name contains the key (the first key that matches wins), at lr x
    multiplier; then one group of the others at lr. Empty groups are left out."""
    groups: dict[str, list[nn.Parameter]] = {key: [] for key in (*lr_multipliers, "")}
    for name, parameter in module.named_parameters():
        if parameter.requires_grad:
            groups[next((key for key in lr_multipliers if key in name), "")].append(parameter)
    return [{"params": params, "lr": lr * lr_multipliers.get(key, 1.0)} for key, params in groups.items() if params]


def adamw(
    module: nn.Module, *, lr: float, weight_decay: float, betas: Sequence[float], lr_multipliers: Mapping[str, float]
) -> torch.optim.AdamW:
    """AdamW over the trainable parameters of module, lr scaled by parameter name
    (:func:`parameter_groups`)."""
    return torch.optim.AdamW(
        parameter_groups(module, lr, lr_multipliers), lr=lr, betas=tuple(betas), weight_decay=weight_decay
    )


def warmup_cosine(optimizer: Optimizer, total_steps: int, *, warmup_steps: int, min_lr: float) -> LambdaLR:
    """Every group's lr grows linearly from 0 over warmup_steps, then follows a half cosine
    to min_lr / base lr x its lr at total_steps (and stays there); the base lr is the
    optimiser's default lr (``optimizer.defaults["lr"]``), so the groups keep their ratios."""
    min_factor = min_lr / optimizer.defaults["lr"]

    def factor(step: int) -> float:
        if step < warmup_steps:
            return (step + 1) / warmup_steps
        progress = min(1.0, (step - warmup_steps) / max(1, total_steps - warmup_steps))
        return min_factor + (1 - min_factor) * 0.5 * (1 + math.cos(math.pi * progress))

    return LambdaLR(optimizer, factor)
