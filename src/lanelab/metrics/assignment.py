"""Minimum-cost assignment that breaks ties exactly as the official OpenLane evaluator.

The official evaluator (``eval/LANE_evaluation/lane3d/utils/MinCostFlow.py``) matches GT
and predicted lanes with ortools' ``SimpleMinCostFlow``: min(G, P) units of flow from a
source through GT node i -> prediction node j (unit capacity, cost[i, j]) to a sink, over
the complete bipartite graph. Any exact solver finds an assignment of the same total cost,
but integer costs tie often (the evaluator truncates summed distances), and which of the
tied assignments is returned changes the metric. So this module re-implements the
algorithm ortools runs -- Goldberg's cost-scaling push-relabel ("An Efficient
Implementation of a Scaling Minimum-Cost Flow Algorithm", J. Algorithms 22(1), 1997) with
ortools' parameters and visiting orders:

- the graph ortools builds: the user's arcs, then an extra source feeding the supply node
  and an extra sink drained by the demand node; arcs sorted by tail (stably), and each
  node visiting first the reverses of its incoming arcs, then its outgoing arcs, both by
  arc index;
- costs multiplied by (number of nodes + 1); epsilon starts at the largest scaled cost and
  is divided by 5 (integer division) before each refine, down to 1;
- each refine saturates the admissible arcs, then discharges active nodes from a LIFO
  stack (initially by increasing node index) with look-ahead relabelling of the heads and
  "first admissible arc" bookkeeping; price updates are off (ortools' default).

The matching found is optimal whatever the visiting order; the order only decides ties.
"""

from __future__ import annotations

import numpy as np

_ALPHA = 5  # ortools' epsilon divisor (flag min_cost_flow_alpha)


def min_cost_assignment(cost: np.ndarray) -> list[tuple[int, int]]:
    """The official solver's min(G, P) pairs (row, col) for an integer cost (G, P), by row."""
    G, P = cost.shape
    if G == 0 or P == 0:
        return []
    return _CostScalingFlow(cost.astype(np.int64).tolist()).solve()


class _CostScalingFlow:
    """One assignment problem as ortools' flow network, solved by cost scaling.

    Nodes: 0 source, 1..G GT lanes, G+1..G+P predictions, G+P+1 sink, then the extra
    source S = G+P+2 and extra sink T = G+P+3 that carry the supply. Half-arcs: h < A is
    direct arc h; h >= A is the reverse of arc h - A.
    """

    def __init__(self, cost: list[list[int]]) -> None:
        G, P = len(cost), len(cost[0])
        self.G, self.P = G, P
        sink, S, T = G + P + 1, G + P + 2, G + P + 3
        n = G + P + 4
        supply = min(G, P)
        arcs = [(0, 1 + i, 1, 0) for i in range(G)]
        arcs += [(1 + i, 1 + G + j, 1, cost[i][j]) for i in range(G) for j in range(P)]
        arcs += [(1 + G + j, sink, 1, 0) for j in range(P)]
        # ortools adds S -> source, then sink -> T, and its static graph sorts arcs by tail.
        arcs += [(sink, T, supply, 0), (S, 0, supply, 0)]
        A = len(arcs)
        scale = n + 1
        self.tail = [a[0] for a in arcs] + [a[1] for a in arcs]
        self.head = [a[1] for a in arcs] + [a[0] for a in arcs]
        self.residual = [a[2] for a in arcs] + [0] * A
        self.cost = [a[3] * scale for a in arcs] + [-a[3] * scale for a in arcs]
        self.A = A
        incoming: list[list[int]] = [[] for _ in range(n)]
        outgoing: list[list[int]] = [[] for _ in range(n)]
        for a, (t, h, _, _) in enumerate(arcs):
            outgoing[t].append(a)
            incoming[h].append(A + a)
        self.adjacency = [incoming[v] + outgoing[v] for v in range(n)]
        self.potential = [0] * n
        self.excess = [0] * n
        self.excess[S], self.excess[T] = supply, -supply
        # Position in adjacency[v] where the scan for an admissible arc resumes (None: nil).
        self.first: list[int | None] = [0 if adj else None for adj in self.adjacency]
        self.epsilon = max([1] + [abs(c) for c in self.cost[:A]])
        self.stack: list[int] = []

    def solve(self) -> list[tuple[int, int]]:
        while True:
            self.epsilon = max(self.epsilon // _ALPHA, 1)
            self._refine()
            if self.epsilon == 1:
                break
        G, P, A = self.G, self.P, self.A
        pairs = []
        for a in range(G, G + G * P):
            if self.residual[A + a] > 0:
                pairs.append(divmod(a - G, P))
        return pairs

    def _admissible(self, h: int, tail_potential: int) -> bool:
        return self.residual[h] > 0 and (
            self.cost[h] + tail_potential - self.potential[self.head[h]] < 0
        )

    def _push(self, flow: int, h: int, tail: int) -> None:
        self.residual[h] -= flow
        self.residual[h + self.A if h < self.A else h - self.A] += flow
        self.excess[tail] -= flow
        self.excess[self.head[h]] += flow

    def _refine(self) -> None:
        for v, adjacency in enumerate(self.adjacency):
            start = self.first[v]
            if start is not None:
                tail_potential = self.potential[v]
                for h in adjacency[start:]:
                    if self._admissible(h, tail_potential):
                        self._push(self.residual[h], h, v)
            self.first[v] = None
        self.stack = [v for v, e in enumerate(self.excess) if e > 0]
        while self.stack:
            self._discharge(self.stack.pop())

    def _discharge(self, v: int) -> None:
        adjacency, excess = self.adjacency[v], self.excess
        while True:
            tail_potential = self.potential[v]
            start = self.first[v]
            if start is not None:
                for position in range(start, len(adjacency)):
                    h = adjacency[position]
                    if not self._admissible(h, tail_potential):
                        continue
                    w = self.head[h]
                    if not self._look_ahead(h, tail_potential, w):
                        continue
                    was_active = excess[w] > 0
                    self._push(min(excess[v], self.residual[h]), h, v)
                    if excess[w] > 0 and not was_active:
                        self.stack.append(w)
                    if excess[v] == 0:
                        self.first[v] = position
                        return
            self._relabel(v)

    def _look_ahead(self, in_arc: int, in_tail_potential: int, w: int) -> bool:
        """Relabel w now if it could not pass on flow pushed along in_arc."""
        if self.excess[w] < 0:
            return True
        start = self.first[w]
        if start is not None:
            potential = self.potential[w]
            adjacency = self.adjacency[w]
            for position in range(start, len(adjacency)):
                if self._admissible(adjacency[position], potential):
                    self.first[w] = position
                    return True
        self._relabel(w)
        return self._admissible(in_arc, in_tail_potential)

    def _relabel(self, v: int) -> None:
        guaranteed = self.potential[v] - self.epsilon
        lowest = previous_lowest = None  # highest potentials at which an arc stays inadmissible
        first_arc = None
        for position, h in enumerate(self.adjacency[v]):
            if self.residual[h] > 0:
                limit = self.potential[self.head[h]] - self.cost[h]
                if lowest is None or limit > lowest:
                    if limit > guaranteed:
                        self.potential[v] = guaranteed
                        self.first[v] = position
                        return
                    previous_lowest, lowest, first_arc = lowest, limit, position
        if lowest is None:  # no residual arc leaves v
            self.potential[v] = guaranteed
            self.first[v] = 0 if self.adjacency[v] else None
            return
        self.potential[v] = lowest - self.epsilon
        if previous_lowest is None or previous_lowest <= self.potential[v]:
            self.first[v] = first_arc
        else:
            self.first[v] = 0
