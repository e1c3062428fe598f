"""lanelab.runtime.ranking: with a margin, ties and near-ties (below it) resolve to the earlier
candidate, whatever float noise the backend adds, and real differences above it still decide;
picks are recorded and replayed, and a replayed pick's deviation says how near a tie it was."""

from __future__ import annotations

import torch

import math

import pytest

from lanelab.runtime.ranking import deviation, forcing_picks, recording_picks, topk


def stable_topk(values: torch.Tensor, k: int, margin: float) -> torch.Tensor:
    return topk(values, k, margin=margin)[1]


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


def test_picks_are_recorded_and_replayed_with_their_deviation() -> None:
    values = torch.tensor([[3.0, 1.0, 1.0 + 1e-6, 2.0]])
    with recording_picks() as picks:
        nearest, index = topk(values, 2)
        topk(values, 1, largest=True)
    assert index.tolist() == [[1, 2]] and nearest.tolist() == values[:, [1, 2]].tolist()
    assert [p.tolist() for p in picks] == [[[1, 2]], [[0]]]
    other = [torch.tensor([[2, 1]]), torch.tensor([[3]])]  # a near-tie swapped; a real difference
    with forcing_picks(other) as deviations:
        assert topk(values, 2)[1].tolist() == [[2, 1]]
        assert topk(values, 1, largest=True)[1].tolist() == [[3]]
    assert deviations[0] < 1e-6 and math.isclose(deviations[1], 1 / 4)  # |2 - 3| / (1 + 3)
    assert topk(values, 1)[1].tolist() == [[1]]  # outside: its own choice again
    with pytest.raises(RuntimeError, match="1 picks, 2 were given"), forcing_picks(other):
        topk(values, 2)


def test_an_invalid_pick_against_a_valid_best_is_no_tie() -> None:
    distances = torch.tensor([[0.5, float("inf"), float("inf")]])
    assert deviation(distances, torch.tensor([[1, 2]])) == float("inf")  # two invalid keys where a valid one was best
    assert deviation(distances, torch.tensor([[0, 1]])) == 0.0  # the best and an invalid one, as topk takes them
    assert deviation(distances, torch.tensor([[1, 0]])) == float("inf")  # an invalid key where a valid one was best
