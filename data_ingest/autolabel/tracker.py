"""Accumulation and tracking of lane lines along a drive (SparseLaneSTP, supplementary E).

A Kalman-filter tracker tailored to lines rather than objects. A track is a line on the road
surface: a chain of nodes at fixed arc lengths along the trajectory (node k at
``k * node_spacing_m``), each with a lateral offset ``d`` and its variance. Lines do not
move, so the filter's state is static but for a small process noise per frame (the surface
is a model, a node may settle); its measurements are the observations of
:mod:`~data_ingest.autolabel.projection`, each node's noise from its depth. Frame by frame
(:meth:`LineTracker.step`):

1. **association**: an observation's cost to a track is the mean lateral distance over the
   nodes both cover, weighted by how well both know each node; with too little overlap, the distance to the track's end extended along
   its last direction (a line seen further on, or after a gap); plus ``category_penalty_m``
   when the detection is known to be another kind of line (:func:`different_kinds`) than the
   category the track's detections voted for (a curb a metre beyond an edge line is seen from
   afar, where a detection's bias is a metre too).
   Observations and tracks are paired one-to-one at least total cost (Hungarian), within ``gate_m``;
2. **update**: each node of a paired observation updates the track's node (the Kalman gain
   weighs it against what the track knows); nodes beyond the track extend it;
3. **birth**: an unpaired observation starts a tentative track; a tentative track becomes a
   line, with the next stable id, once detected in ``confirm_hits`` frames, and is dropped
   if it goes undetected twice first (a false detection rarely repeats at the same place);
4. **death**: a line that should have been seen (the caller says which are in view) but was
   not for more than ``max_misses`` frames ends, as does one the ego has passed; an ended line
   is kept, and may be taken up again by an observation that continues it;
5. **merge**: two live tracks that cover the same nodes within ``merge_m`` are one line (a
   detection split by an occlusion, say): the younger is fused into the older, which keeps its id.

:meth:`LineTracker.lines` returns the lines: tracks of one line that a stretch without a good
view split (traffic hid it, a lane change took the ego away) joined end to start, each smoothed
along its length (:mod:`~data_ingest.autolabel.line_smoother`), which fills such gaps.
"""

from __future__ import annotations

import copy
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from data_ingest.autolabel.line_smoother import smooth_line
from data_ingest.autolabel.projection import Observation
from lanelab.lanes import LANE_CATEGORY_NAMES, NO_TRACK

MIN_OVERLAP_NODES = 3  # nodes an observation must share with a track to compare offsets there
MERGE_OVERLAP_NODES = 5
EXTEND_FIT_NODES = 10  # the track's last nodes that give its direction beyond its end
MAX_EXTEND_M = 25.0  # an observation may continue a track after a gap this long
TENTATIVE_MISSES = 2
_FAR = 1e9


def line_kind(category: int) -> str | None:
    """What a line is made of, which stays the same along it: a curbside, white paint or yellow
    paint, read from the category's name (lanelab.lanes.LANE_CATEGORY_NAMES); None for "unknown"
    (a detector that does not classify). Dashed and solid alternate along one line (a
    no-passing zone), so they are one kind."""
    name = LANE_CATEGORY_NAMES.get(category, "")
    if name == "unknown":
        return None
    return "curb" if "curbside" in name else "yellow" if "yellow" in name else "white"


def different_kinds(a: int, b: int) -> bool:
    """Whether categories a and b are known to be different kinds of line."""
    kinds = line_kind(a), line_kind(b)
    return None not in kinds and kinds[0] != kinds[1]


@dataclass
class Track:
    """A line being tracked: offsets d (n,) and variances var (n,) of nodes ``first`` ..
    ``first + n - 1`` (NaN and inf where no observation reached yet), and the frame each node
    was last updated in, seen (n,) (-1: never)."""

    key: int
    first: int
    d: np.ndarray
    var: np.ndarray
    seen: np.ndarray
    last_frame: int
    hits: int = 1
    misses: int = 0
    track_id: int = NO_TRACK
    ended: bool = False
    votes: dict[int, float] = field(default_factory=lambda: defaultdict(float))

    @property
    def confirmed(self) -> bool:
        return self.track_id != NO_TRACK

    @property
    def nodes(self) -> np.ndarray:
        return np.arange(self.first, self.first + len(self.d))

    @property
    def category(self) -> int:
        """The category its detections voted for most (votes weighted by detection score)."""
        return max(self.votes, key=self.votes.get)

    def observed(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """nodes, d, var of the nodes that have an estimate."""
        known = np.isfinite(self.d)
        return self.nodes[known], self.d[known], self.var[known]

    def cover(self, nodes: np.ndarray) -> None:
        """Grow the chain so that it covers ``nodes`` (sorted)."""
        before = max(self.first - int(nodes[0]), 0)
        after = max(int(nodes[-1]) - (self.first + len(self.d) - 1), 0)
        if before or after:
            self.d = np.concatenate([np.full(before, np.nan), self.d, np.full(after, np.nan)])
            self.var = np.concatenate([np.full(before, np.inf), self.var, np.full(after, np.inf)])
            self.seen = np.concatenate([np.full(before, -1), self.seen, np.full(after, -1)])
            self.first -= before

    def update(self, observation: Observation, process_noise_m: float) -> None:
        """Fuse an observation into the nodes it covers (a scalar Kalman update per node)."""
        self.cover(observation.nodes)
        at = observation.nodes - self.first
        # A node's uncertainty grows between its observations (the static state's process noise).
        prior = self.var[at] + process_noise_m**2 * (observation.frame - self.seen[at])
        self.d[at], self.var[at] = _fuse(self.d[at], prior, observation.d, observation.sigma**2)
        self.seen[at] = observation.frame
        self.last_frame = observation.frame
        self.hits += 1
        self.misses = 0
        self.ended = False
        self.votes[observation.category] += observation.score

    def absorb(self, other: Track) -> None:
        """Fuse another track of the same line into this one (inverse-variance per node)."""
        nodes, d, var = other.observed()
        self.cover(nodes)
        at = nodes - self.first
        self.d[at], self.var[at] = _fuse(self.d[at], self.var[at], d, var)
        self.seen[at] = np.maximum(self.seen[at], other.seen[other.nodes[np.isfinite(other.d)] - other.first])
        self.hits += other.hits
        self.last_frame = max(self.last_frame, other.last_frame)
        for category, vote in other.votes.items():
            self.votes[category] += vote


def _known(track: Track, max_std_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """nodes, d, var of the track's nodes known to within max_std_m."""
    nodes, d, var = track.observed()
    known = var <= max_std_m**2
    return nodes[known], d[known], var[known]


def _fuse(d: np.ndarray, var: np.ndarray, z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update of estimates d (M,) of variance var (M,) (NaN, inf: none yet) by
    measurements z (M,) of variance r (M,): the updated estimates and variances."""
    new = ~np.isfinite(d)
    with np.errstate(invalid="ignore"):
        gain = var / (var + r)
        return np.where(new, z, d + gain * (z - d)), np.where(new, r, (1 - gain) * var)


@dataclass(frozen=True)
class Line:
    """A tracked lane line, smoothed: nodes (M,) consecutive node indices, d (M,) offsets (m)."""

    track_id: int
    category: int
    nodes: np.ndarray
    d: np.ndarray
    ended: bool


class LineTracker:
    """Tracks lane lines through the observations of a drive's frames, in time order."""

    def __init__(self, node_spacing_m: float, gate_m: float, confirm_hits: int, max_misses: int, merge_m: float,
                 process_noise_m: float, category_penalty_m: float) -> None:
        self.node_spacing_m = node_spacing_m
        self.gate_m, self.merge_m, self.category_penalty_m = gate_m, merge_m, category_penalty_m
        self.confirm_hits, self.max_misses = confirm_hits, max_misses
        self.process_noise_m = process_noise_m
        self.tracks: list[Track] = []
        self._births = 0
        self._ids = 0

    def step(self, frame: int, observations: Sequence[Observation], in_view: Callable[[Track], bool],
             passed_node: int) -> None:
        """Take frame ``frame``'s observations. in_view(track): whether the track should have been
        detected in this frame; passed_node: the first node still ahead of the camera's view
        (tracks that end before it are behind the ego)."""
        candidates = [track for track in self.tracks if not track.ended or track.confirmed]
        cost = np.array([[self._cost(obs, track) for track in candidates] for obs in observations]).reshape(
            len(observations), len(candidates))
        rows, cols = linear_sum_assignment(np.minimum(cost, _FAR)) if cost.size else ([], [])
        paired = {int(r): candidates[c] for r, c in zip(rows, cols) if cost[r, c] <= self.gate_m}
        for k, observation in enumerate(observations):
            track = paired.get(k)
            if track is not None:
                track.update(observation, self.process_noise_m)
                if not track.confirmed and track.hits >= self.confirm_hits:
                    track.track_id, self._ids = self._ids, self._ids + 1
            else:
                self._birth(observation)
        seen = {id(track) for track in paired.values()}
        survivors = []
        for track in self.tracks:
            if id(track) not in seen and not track.ended:
                if track.first + len(track.d) <= passed_node:
                    track.ended = True
                elif in_view(track):
                    track.misses += 1
                    track.ended = track.confirmed and track.misses > self.max_misses
                    if not track.confirmed and track.misses >= TENTATIVE_MISSES:
                        continue
            if track.ended and not track.confirmed:
                continue
            survivors.append(track)
        self.tracks = survivors
        self._merge()

    def lines(self, curvature_noise: float, min_length_m: float, max_std_m: float, max_gap_m: float) -> list[Line]:
        """The confirmed tracks, by id, smoothed along their length: each from its first to its
        last node known to within ``max_std_m`` (a line or a part of it seen only from afar,
        where a pixel is metres, is no label), if that is at least ``min_length_m`` long. Tracks
        of one line that a stretch of up to ``max_gap_m`` without a good view split are joined
        first (:meth:`_join_gaps`); the smoother fills the gap."""
        lines = []
        for track in self._join_gaps(max_std_m, max_gap_m):
            nodes, d, var = _known(track, max_std_m)
            if len(nodes) < 2 or np.ptp(nodes) * self.node_spacing_m < min_length_m:
                continue
            all_nodes = np.arange(nodes[0], nodes[-1] + 1)
            measured = np.full(len(all_nodes), np.inf)
            measured[nodes - nodes[0]] = var
            smoothed = smooth_line(all_nodes * self.node_spacing_m, np.interp(all_nodes, nodes, d), measured,
                                   curvature_noise)
            lines.append(Line(track.track_id, track.category, all_nodes, smoothed, track.ended))
        return lines

    def _join_gaps(self, max_std_m: float, max_gap_m: float) -> list[Track]:
        """The confirmed tracks by id, those of one line joined: a track that starts after another
        one's end, within ``max_gap_m``, of the same kind, where the two, each extended straight
        across the gap, meet within ``gate_m`` at its middle (a line hidden by traffic or a lane
        change for a while, whose track ended and another began). The earlier keeps its id."""
        tracks = [copy.deepcopy(t) for t in self.tracks if t.confirmed]  # the tracker's own stay as they are
        known = {id(t): _known(t, max_std_m)[0] for t in tracks}
        joined: list[Track] = []
        for track in sorted((t for t in tracks if len(known[id(t)]) >= 2), key=lambda t: known[id(t)][0]):
            costs = [(self._gap_cost(before, track, max_std_m, max_gap_m), k) for k, before in enumerate(joined)]
            cost, k = min(costs, default=(_FAR, -1))
            if cost <= self.gate_m:
                joined[k].absorb(track)
                joined[k].ended = track.ended
            else:
                joined.append(track)
        return sorted(joined, key=lambda t: t.track_id)

    def _gap_cost(self, before: Track, after: Track, max_std_m: float, max_gap_m: float) -> float:
        """Lateral distance at the gap's middle of ``before`` and ``after``, each extended straight
        across it; _FAR when ``after`` does not start within max_gap_m after ``before`` ends, or
        they are different kinds of line."""
        a_nodes, a_d, _ = _known(before, max_std_m)
        b_nodes, b_d, _ = _known(after, max_std_m)
        gap = int(b_nodes[0] - a_nodes[-1])
        if not 0 < gap * self.node_spacing_m <= max_gap_m or different_kinds(before.category, after.category):
            return _FAR
        middle = (a_nodes[-1] + b_nodes[0]) / 2
        tail, head = slice(-EXTEND_FIT_NODES, None), slice(None, EXTEND_FIT_NODES)
        a_at = np.polyval(np.polyfit(a_nodes[tail].astype(float), a_d[tail], 1), middle)
        b_at = np.polyval(np.polyfit(b_nodes[head].astype(float), b_d[head], 1), middle)
        return float(abs(a_at - b_at))

    def _birth(self, observation: Observation) -> None:
        size = len(observation.nodes)
        track = Track(self._births, int(observation.nodes[0]), np.full(size, np.nan), np.full(size, np.inf),
                      np.full(size, -1), observation.frame, hits=0)
        self._births += 1
        track.update(observation, self.process_noise_m)
        if self.confirm_hits <= 1:
            track.track_id, self._ids = self._ids, self._ids + 1
        self.tracks.append(track)

    def _cost(self, observation: Observation, track: Track) -> float:
        """Mean lateral distance of the observation to the track (over shared nodes, else to the
        track's extension beyond its end), plus the category penalty; _FAR when they cannot be compared."""
        penalty = self.category_penalty_m if different_kinds(observation.category, track.category) else 0.0
        return self._distance(observation, track) + penalty

    def _distance(self, observation: Observation, track: Track) -> float:
        nodes, d, var = track.observed()
        shared, at_obs, at_track = np.intersect1d(observation.nodes, nodes, return_indices=True)
        if len(shared) >= MIN_OVERLAP_NODES:
            weight = 1 / (observation.sigma[at_obs] ** 2 + var[at_track])
            return float(np.average(np.abs(observation.d[at_obs] - d[at_track]), weights=weight))
        # Too little overlap: an observation that starts at most a few nodes before the track's end
        # (a line seen further on, or after a gap) is compared with the track extended.
        gap = int(observation.nodes[0] - nodes[-1])
        if not -MIN_OVERLAP_NODES < gap <= MAX_EXTEND_M / self.node_spacing_m or len(nodes) < 2:
            return _FAR
        tail = slice(-EXTEND_FIT_NODES, None)
        slope, offset = np.polyfit(nodes[tail].astype(float), d[tail], 1)
        head = observation.nodes[:EXTEND_FIT_NODES]
        return float(np.abs(observation.d[:EXTEND_FIT_NODES] - (slope * head + offset)).mean())

    def _merge(self) -> None:
        """Fuse live tracks that are the same line (see the module's docstring)."""
        live = sorted((t for t in self.tracks if not t.ended),
                      key=lambda t: (not t.confirmed, t.track_id if t.confirmed else 0, t.key))
        gone: set[int] = set()
        for i, keep in enumerate(live):
            if id(keep) in gone:
                continue
            for other in live[i + 1:]:
                if id(other) in gone:
                    continue
                a_nodes, a_d, a_var = keep.observed()
                b_nodes, b_d, b_var = other.observed()
                shared, at_a, at_b = np.intersect1d(a_nodes, b_nodes, return_indices=True)
                if len(shared) < MERGE_OVERLAP_NODES:
                    continue
                weight = 1 / (a_var[at_a] + b_var[at_b])
                if np.average(np.abs(a_d[at_a] - b_d[at_b]), weights=weight) < self.merge_m:
                    keep.absorb(other)
                    gone.add(id(other))
        self.tracks = [t for t in self.tracks if id(t) not in gone]
