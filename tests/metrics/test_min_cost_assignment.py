"""The assignment solver: optimal, and tie-breaking as the official ortools flow."""

import itertools

import numpy as np
import pytest

from lanelab.metrics.assignment import min_cost_assignment

# Tied problems with the pairs ortools 9.3's SimpleMinCostFlow returns for them, built as the
# official MinCostFlow.py builds the graph (recorded by running it).
OFFICIAL_TIE_BREAKS = [
    ([[0], [150], [50], [0]], [(3, 0)]),
    ([[50, 50], [50, 50], [50, 150]], [(1, 1), (2, 0)]),
    ([[18, 93, 21], [31, 143, 34]], [(0, 2), (1, 0)]),
    ([[406, 93, 66], [109, 19, 66], [170, 52, 25]], [(0, 1), (1, 0), (2, 2)]),
    (
        [[100, 50, 50, 0], [0, 0, 0, 150], [100, 150, 100, 100], [150, 100, 100, 100],
         [100, 150, 50, 150]],
        [(0, 3), (1, 0), (3, 1), (4, 2)],
    ),
    (
        [[0, 100, 0, 0, 100], [0, 100, 150, 0, 100], [50, 150, 150, 100, 100],
         [100, 100, 100, 0, 150], [100, 150, 100, 50, 0]],
        [(0, 2), (1, 1), (2, 0), (3, 3), (4, 4)],
    ),
]


@pytest.mark.parametrize("cost, expected", OFFICIAL_TIE_BREAKS)
def test_ties_are_broken_like_the_official_solver(cost, expected):
    assert min_cost_assignment(np.array(cost)) == expected


def brute_force_cost(cost: np.ndarray) -> int:
    G, P = cost.shape
    if G <= P:
        return min(sum(cost[i, c] for i, c in enumerate(cols)) for cols in itertools.permutations(range(P), G))
    return brute_force_cost(cost.T)


def test_assignment_is_optimal_and_one_to_one():
    rng = np.random.default_rng(0)
    for _ in range(200):
        G, P = rng.integers(1, 6, size=2)
        cost = rng.integers(0, 300, size=(G, P))
        pairs = min_cost_assignment(cost)
        rows, cols = zip(*pairs)
        assert len(pairs) == min(G, P)
        assert len(set(rows)) == len(rows) and len(set(cols)) == len(cols)
        assert list(rows) == sorted(rows)
        assert sum(cost[r, c] for r, c in pairs) == brute_force_cost(cost)


def test_empty_sides_give_no_pairs():
    assert min_cost_assignment(np.zeros((0, 3), dtype=int)) == []
    assert min_cost_assignment(np.zeros((2, 0), dtype=int)) == []
