import torch

from lanelab.models.parts.lane_nms import suppress_duplicates

Y = torch.linspace(3.0, 103.0, 100)


def lanes(*x0: float, slope: float = 0.0) -> torch.Tensor:
    """(1, N, S) lateral positions of straight lanes starting at x0."""
    return torch.tensor(x0)[None, :, None] + slope * Y


def test_the_less_confident_of_two_lines_on_one_lane_is_dropped_and_distinct_lanes_stay():
    x = lanes(1.75, 1.9, -1.75, 1.2)  # 0 and 1 find the same lane; 3 lies 0.55 m from 0: a curb beside a line
    score = torch.tensor([[0.6, 0.9, 0.8, 0.7]])
    valid = torch.ones(1, 4, dtype=torch.bool)
    keep = suppress_duplicates(x, score, valid, Y <= 40.0, distance=0.5)
    assert keep.tolist() == [[False, True, True, True]]


def test_invalid_lines_suppress_nothing_and_far_drift_does_not_count():
    x = lanes(0.0, 0.1)
    x[0, 1] += torch.where(Y > 40.0, 5.0, 0.0)  # the duplicate drifts off only beyond the near range
    score = torch.tensor([[0.9, 0.5]])
    assert suppress_duplicates(x, score, torch.tensor([[True, True]]), Y <= 40.0, 0.5).tolist() == [[True, False]]
    assert suppress_duplicates(x, score, torch.tensor([[False, True]]), Y <= 40.0, 0.5).tolist() == [[False, True]]
