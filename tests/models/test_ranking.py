"""stable_topk: ties and near-ties (below the margin) resolve to the earlier candidate, whatever
float noise the backend adds; real differences above the margin still decide."""

from __future__ import annotations

import torch

from lanelab.models.ranking import stable_topk


def test_exact_ties_go_to_the_earlier_candidate() -> None:
    values = torch.tensor([[3.0, 1.0, 1.0, 1.0, 2.0]])
    assert stable_topk(values, 2, margin=1e-3).tolist() == [[1, 2]]
    assert stable_topk(values, 4, margin=1e-3).tolist() == [[1, 2, 3, 4]]


def test_rounding_noise_does_not_change_the_pick_where_plain_topk_flips() -> None:
    # Structurally tied distances (the points before and after a query on a parallel line) with
    # the ~1e-6 disagreement of two backends on top.
    generator = torch.Generator().manual_seed(0)
    base = torch.tensor([10.0, 0.0, 10.0, 20.0, 20.0, 30.0]).repeat(500, 1)
    noisy = [base + 1e-6 * torch.randn(base.shape, generator=generator) for _ in range(2)]
    picks = [stable_topk(values, 2, margin=1e-3) for values in noisy]
    assert torch.equal(picks[0], picks[1]) and (picks[0] == torch.tensor([1, 0])).all()
    plain = [values.topk(2, largest=False).indices for values in noisy]
    assert not torch.equal(plain[0], plain[1])  # what the margin is for


def test_differences_above_the_margin_decide() -> None:
    values = torch.tensor([[0.01, 0.0, 0.02]])
    assert stable_topk(values, 3, margin=1e-3).tolist() == [[1, 0, 2]]
    assert stable_topk(values.to(torch.bfloat16), 1, margin=1e-3).tolist() == [[1]]
