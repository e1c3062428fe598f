"""Munkres' assignment algorithm, breaking ties as the ONCE-3DLanes evaluator does.

The official ONCE-3DLanes evaluator matches lanes with the ``munkres`` package (1.1.x),
which runs the textbook Munkres steps (Bob Pilgrim's formulation: reduce rows, star
zeros, cover, prime, augment along alternating paths, adjust by the smallest uncovered
value). Any exact solver finds an assignment of the same total cost, but the evaluator's
costs (1 - IoU of top-view masks) tie often -- every lane seen only beyond 10 m costs
exactly 1 -- and which tied assignment comes back decides which pairs are then tested for
a true positive. So this is a re-implementation with the package's visiting orders:

- a rectangular matrix is padded to a square one with zeros;
- zeros are starred scanning rows, then columns, in index order, one per row;
- the search for an uncovered zero starts at the row and column where the previous one
  ended, wraps around, and returns the *last* uncovered zero (in that wrapped order) of
  the first row that has one;
- the smallest uncovered value is added to covered rows, then subtracted from uncovered
  columns, element by element (floating-point results depend on that order).
"""

from __future__ import annotations

from typing import Sequence

_STAR, _PRIME = 1, 2


def munkres_assignment(cost: Sequence[Sequence[float]]) -> list[tuple[int, int]]:
    """min(G, P) pairs (row, col), by row, of a minimum-cost assignment of a (G, P) cost
    matrix: those the munkres package returns."""
    rows, cols = len(cost), len(cost[0]) if cost else 0
    if rows == 0 or cols == 0:
        return []
    return _Munkres(cost).solve(rows, cols)


class _Munkres:
    def __init__(self, cost: Sequence[Sequence[float]]) -> None:
        n = max(len(cost), len(cost[0]))
        self.n = n
        self.C = [list(row) + [0] * (n - len(row)) for row in cost]
        self.C += [[0] * n for _ in range(n - len(cost))]
        self.marked = [[0] * n for _ in range(n)]
        self.row_covered = [False] * n
        self.col_covered = [False] * n

    def solve(self, rows: int, cols: int) -> list[tuple[int, int]]:
        self._reduce_rows()
        self._star_zeros()
        while not self._cover_starred_columns():
            zero = self._prime_zeros()
            while zero is None:
                self._adjust_by_smallest()
                zero = self._prime_zeros()
            self._augment(zero)
        return [(i, j) for i in range(rows) for j in range(cols) if self.marked[i][j] == _STAR]

    def _reduce_rows(self) -> None:
        for row in self.C:
            smallest = min(row)
            for j in range(self.n):
                row[j] -= smallest

    def _star_zeros(self) -> None:
        for i in range(self.n):
            for j in range(self.n):
                if self.C[i][j] == 0 and not self.col_covered[j] and not self.row_covered[i]:
                    self.marked[i][j] = _STAR
                    self.col_covered[j] = self.row_covered[i] = True
                    break
        self._clear_covers()

    def _cover_starred_columns(self) -> bool:
        """Cover the columns holding a star; True when they are all covered (done)."""
        for j in range(self.n):
            if any(self.marked[i][j] == _STAR for i in range(self.n)):
                self.col_covered[j] = True
        return all(self.col_covered)

    def _prime_zeros(self) -> tuple[int, int] | None:
        """Prime uncovered zeros until one has no star in its row (returned), or none is
        left (None)."""
        row = col = 0
        while True:
            found = self._find_uncovered_zero(row, col)
            if found is None:
                return None
            row, col = found
            self.marked[row][col] = _PRIME
            star_col = self._find_in_row(row, _STAR)
            if star_col is None:
                return row, col
            col = star_col
            self.row_covered[row] = True
            self.col_covered[col] = False

    def _find_uncovered_zero(self, row0: int, col0: int) -> tuple[int, int] | None:
        n = self.n
        for i in [(row0 + k) % n for k in range(n)]:
            if self.row_covered[i]:
                continue
            last = None
            for j in [(col0 + k) % n for k in range(n)]:
                if self.C[i][j] == 0 and not self.col_covered[j]:
                    last = j
            if last is not None:
                return i, last
        return None

    def _augment(self, zero: tuple[int, int]) -> None:
        """Swap stars and primes along the alternating path from the primed zero, then
        clear covers and primes."""
        path = [zero]
        while True:
            col = path[-1][1]
            star_row = next((i for i in range(self.n) if self.marked[i][col] == _STAR), None)
            if star_row is None:
                break
            path.append((star_row, col))
            path.append((star_row, self._find_in_row(star_row, _PRIME)))
        for i, j in path:
            self.marked[i][j] = 0 if self.marked[i][j] == _STAR else _STAR
        self._clear_covers()
        for row in self.marked:
            for j in range(self.n):
                if row[j] == _PRIME:
                    row[j] = 0

    def _adjust_by_smallest(self) -> None:
        smallest = min(
            self.C[i][j]
            for i in range(self.n)
            for j in range(self.n)
            if not self.row_covered[i] and not self.col_covered[j]
        )
        for i in range(self.n):
            for j in range(self.n):
                if self.row_covered[i]:
                    self.C[i][j] += smallest
                if not self.col_covered[j]:
                    self.C[i][j] -= smallest

    def _find_in_row(self, row: int, mark: int) -> int | None:
        return next((j for j in range(self.n) if self.marked[row][j] == mark), None)

    def _clear_covers(self) -> None:
        self.row_covered = [False] * self.n
        self.col_covered = [False] * self.n
