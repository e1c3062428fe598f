"""LATR's optimiser set-up: learning-rate multipliers by parameter name, warm-up then cosine."""

from __future__ import annotations

import itertools

import pytest
import torch
from torch import nn

from lanelab.lightning.optim import adamw, parameter_groups, warmup_cosine


class Net(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.backbone = nn.Linear(2, 2)
        self.attention = nn.ModuleDict({"sampling_offsets": nn.Linear(2, 2), "value_proj": nn.Linear(2, 2)})
        self.frozen = nn.Linear(2, 2).requires_grad_(False)


def test_parameter_groups_apply_the_first_matching_multiplier():
    net = Net()
    groups = parameter_groups(net, 1e-3, {"sampling_offsets": 0.1, "attention": 2.0, "unused": 5.0})
    names = {id(p): name for name, p in net.named_parameters()}
    found = [(group["lr"], sorted(names[id(p)] for p in group["params"])) for group in groups]
    # attention.sampling_offsets matches two keys: the first wins. The frozen layer and the
    # empty "unused" group are left out; the rest keeps the base lr.
    assert found == [
        (pytest.approx(1e-4), ["attention.sampling_offsets.bias", "attention.sampling_offsets.weight"]),
        (pytest.approx(2e-3), ["attention.value_proj.bias", "attention.value_proj.weight"]),
        (pytest.approx(1e-3), ["backbone.bias", "backbone.weight"]),
    ]


def test_adamw_takes_its_groups_and_settings():
    optimizer = adamw(Net(), lr=1e-3, weight_decay=0.01, betas=[0.9, 0.99], lr_multipliers={"sampling_offsets": 0.1})
    assert [group["lr"] for group in optimizer.param_groups] == pytest.approx([1e-4, 1e-3])
    assert optimizer.defaults["lr"] == 1e-3 and optimizer.defaults["betas"] == (0.9, 0.99)
    assert all(group["weight_decay"] == 0.01 for group in optimizer.param_groups)


def test_warmup_then_cosine_to_the_minimum():
    optimizer = torch.optim.AdamW([{"params": [nn.Parameter(torch.zeros(1))], "lr": 1.0},
                                   {"params": [nn.Parameter(torch.zeros(1))], "lr": 0.1}], lr=1.0)  # fmt: skip
    scheduler = warmup_cosine(optimizer, 20, warmup_steps=4, min_lr=0.05)
    lrs = []
    for _ in range(25):
        lrs.append([group["lr"] for group in optimizer.param_groups])
        optimizer.step()
        scheduler.step()
    first = [lr for lr, _ in lrs]
    assert first[:4] == pytest.approx([0.25, 0.5, 0.75, 1.0])
    assert all(a >= b for a, b in itertools.pairwise(first[3:]))  # then never up
    assert first[20:] == pytest.approx([0.05] * 5)
    assert all(second == pytest.approx(0.1 * lr) for lr, second in lrs)  # groups keep their ratio
