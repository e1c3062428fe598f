"""LATR's optimiser and learning-rate schedule, which SparseLaneSTP (§5.2) trains with.

LATR (config/release_iccv/latr_1000_baseline.py): AdamW, lr 2e-4, weight decay 0.01, the
deformable attention's sampling offsets at 0.1 x lr (mmcv ``custom_keys``), a cosine schedule
down to 1e-5. Here the schedule runs per optimiser step over the whole training run, after a
linear warm-up, and any parameter-name key (e.g. "backbone") can get its own multiplier.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from torch import nn
from torch.optim import Optimizer
from torch.optim.lr_scheduler import LambdaLR


def parameter_groups(module: nn.Module, lr: float, lr_multipliers: Mapping[str, float]) -> list[dict]:
    """AdamW parameter groups: one per key of lr_multipliers, holding the trainable parameters
    whose name contains the key (the first key that matches wins), at lr x multiplier; then
    one group of the others at lr. Empty groups are left out."""
    groups: dict[str, list[nn.Parameter]] = {key: [] for key in (*lr_multipliers, "")}
    for name, parameter in module.named_parameters():
        if parameter.requires_grad:
            groups[next((key for key in lr_multipliers if key in name), "")].append(parameter)
    return [{"params": params, "lr": lr * lr_multipliers.get(key, 1.0)} for key, params in groups.items() if params]


def warmup_cosine(optimizer: Optimizer, warmup_steps: int, total_steps: int, min_factor: float) -> LambdaLR:
    """Every group's lr grows linearly from 0 over warmup_steps, then follows a half cosine
    to min_factor x its lr at total_steps (and stays there)."""

    def factor(step: int) -> float:
        if step < warmup_steps:
            return (step + 1) / warmup_steps
        progress = min(1.0, (step - warmup_steps) / max(1, total_steps - warmup_steps))
        return min_factor + (1 - min_factor) * 0.5 * (1 + math.cos(math.pi * progress))

    return LambdaLR(optimizer, factor)
