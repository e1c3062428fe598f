"""Munkres' algorithm with the munkres package's tie-breaking (ONCE-3DLanes matching)."""

import itertools

import numpy as np

from lanelab.metrics.munkres import munkres_assignment


def total(cost, pairs):
    return sum(cost[i][j] for i, j in pairs)


def test_examples_of_the_munkres_package():
    square = [[400, 150, 400], [400, 450, 600], [300, 225, 300]]
    assert total(square, munkres_assignment(square)) == 850
    rectangular = [[400, 150, 400, 1], [400, 450, 600, 2], [300, 225, 300, 3]]
    assert total(rectangular, munkres_assignment(rectangular)) == 452


def test_a_tie_broken_as_the_package_breaks_it():
    # Traced by hand: rows reduced to [[0,0,0],[0,1,1],[1,0,0]]; (0,0) and (2,1) starred;
    # the search primes the *last* uncovered zero of row 0, (0,2), then (1,0), and the
    # alternating path (1,0) (0,0) (0,2) gives the stars below. Another optimum of cost 1,
    # [(0,1), (1,0), (2,2)], is what other solvers return.
    cost = [[1.0, 1.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 0.0]]
    assert munkres_assignment(cost) == [(0, 2), (1, 0), (2, 1)]


def test_all_equal_costs():
    assert munkres_assignment([[1.0] * 3] * 3) == [(0, 0), (1, 1), (2, 2)]
    assert munkres_assignment([[1.0] * 3] * 2) == [(0, 0), (1, 1)]
    # More rows than columns: the zero padding column is starred in row 0 first, and row 0
    # stays unmatched in the end (traced by hand, as the package returns it).
    assert munkres_assignment([[1.0] * 2] * 3) == [(1, 1), (2, 0)]


def test_empty_matrices_have_no_pairs():
    assert munkres_assignment([]) == [] and munkres_assignment([[]]) == []


def test_optimal_on_random_tied_matrices():
    rng = np.random.default_rng(0)
    for _ in range(200):
        rows, cols = (int(n) for n in rng.integers(1, 5, 2))
        cost = (1.0 - rng.choice([0.0, 0.25, 0.5, 1.0], (rows, cols))).tolist()
        pairs = munkres_assignment(cost)
        assert len(pairs) == min(rows, cols)
        assert len({i for i, _ in pairs}) == len({j for _, j in pairs}) == len(pairs)
        best = min(
            total(cost, zip(range(rows), perm)) if rows <= cols
            else total(cost, zip(perm, range(cols)))
            for perm in itertools.permutations(range(max(rows, cols)), min(rows, cols))
        )
        assert total(cost, pairs) == best
