"""Temporal consistency: frame-to-frame jitter of lanes after ego-motion compensation.

Neither paper measures it; lanelab defines it as follows. For each pair of consecutive
frames (t-1, t) of a clip:

1. Frame t-1's lanes are carried into frame t with the ego poses (DESIGN.md):
   ``p_t = T_world_lane(t)^-1 · T_world_lane(t-1) · p_(t-1)``. Lanes are static in the
   world, so a perfect, consistent detector puts them where frame t sees them.
2. Each carried lane is associated with at most one lane of frame t: lanes with the same
   track id pair up (ground truth: its track id; predictions: the track id of the GT lane
   the OpenLane matching paired it with, see :func:`matched_track_ids`). The lanes left
   pair greedily, nearest first, by their mean lateral distance, if it is below a gate
   (default 1.5 m, the OpenLane per-point threshold), so that a lane that vanishes is not
   paired with its neighbour 3.5 m away.
3. A pair's jitter is the mean lateral deviation |x_t(y) - x_(t-1 -> t)(y)| over the y
   samples (3 .. 102 m, the OpenLane grid) both lanes cover, both linearly interpolated in
   y; a pair with fewer than two common samples has none.

The figure is the mean jitter over all pairs of all consecutive frames of all clips, in
metres, given for the predictions and, next to it, for the ground truth: the labels' own
jitter (label noise, pose error), the floor a detector is compared with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from lanelab.lanes import NO_TRACK
from lanelab.metrics.openlane import FrameResult, OpenLaneConfig


@dataclass(frozen=True)
class PosedLanes:
    """The lanes of one frame with the frame's pose.

    T_world_lane: (4, 4) ego pose. lanes[i]: (N_i, 3) points in the frame's lane frame
    (x right, y forward, z up), visible points only. track_ids[i]: lane i's identity
    across frames, NO_TRACK if unknown.
    """

    T_world_lane: np.ndarray
    lanes: Sequence[np.ndarray]
    track_ids: Sequence[int]


def matched_track_ids(
    result: FrameResult, gt_track_ids: Sequence[int], num_predictions: int
) -> list[int]:
    """Track ids of a frame's predictions: that of the GT lane each was matched to by
    :func:`~lanelab.metrics.openlane.evaluate_frame`, NO_TRACK if unmatched."""
    ids = [NO_TRACK] * num_predictions
    for gt_index, pred_index in result.matched:
        ids[pred_index] = gt_track_ids[gt_index]
    return ids


def carry_lanes(previous: PosedLanes, T_world_lane: np.ndarray) -> list[np.ndarray]:
    """previous's lanes (N_i, 3) expressed in the lane frame of pose T_world_lane (4, 4)."""
    T = np.linalg.inv(T_world_lane) @ previous.T_world_lane
    return [np.asarray(lane, float) @ T[:3, :3].T + T[:3, 3] for lane in previous.lanes]


def frame_jitter(
    previous: PosedLanes,
    current: PosedLanes,
    y_samples: np.ndarray = OpenLaneConfig().y_samples,
    gate: float = 1.5,
) -> np.ndarray:
    """(K,) jitter in metres of the K associated lane pairs of two consecutive frames."""
    carried = carry_lanes(previous, current.T_world_lane)
    lanes = [np.asarray(lane, float) for lane in current.lanes]
    # deviation[i, j]: mean |dx| of carried lane i and current lane j; NaN without overlap.
    deviation = np.array([[_mean_lateral_deviation(a, b, y_samples) for b in lanes]
                          for a in carried]).reshape(len(carried), len(lanes))
    pairs = _pairs_by_track(previous.track_ids, current.track_ids)
    free_rows = sorted(set(range(len(carried))) - {i for i, _ in pairs})
    free_cols = sorted(set(range(len(lanes))) - {j for _, j in pairs})
    pairs += _nearest_pairs(deviation, free_rows, free_cols, gate)
    values = np.array([deviation[i, j] for i, j in pairs])
    return values[~np.isnan(values)]


def clip_jitter(
    frames: Sequence[PosedLanes],
    y_samples: np.ndarray = OpenLaneConfig().y_samples,
    gate: float = 1.5,
) -> np.ndarray:
    """Jitter of every associated pair of every two consecutive frames of a clip (in time
    order); an unlabeled frame is one with no lanes."""
    values = [frame_jitter(a, b, y_samples, gate) for a, b in zip(frames[:-1], frames[1:])]
    return np.concatenate(values) if values else np.zeros(0)


def temporal_consistency(
    predicted_clips: Iterable[Sequence[PosedLanes]],
    gt_clips: Iterable[Sequence[PosedLanes]],
    y_samples: np.ndarray = OpenLaneConfig().y_samples,
    gate: float = 1.5,
) -> dict[str, float | int]:
    """Mean jitter (metres) of the predictions and of the ground truth over clips.

    Returns jitter and gt_jitter (NaN without pairs), and pairs and gt_pairs, the numbers of
    lane pairs they average over.
    """
    result: dict[str, float | int] = {}
    for prefix, clips in (("", predicted_clips), ("gt_", gt_clips)):
        values = np.concatenate([clip_jitter(c, y_samples, gate) for c in clips] + [np.zeros(0)])
        result[f"{prefix}jitter"] = float(values.mean()) if len(values) else float("nan")
        result[f"{prefix}pairs"] = len(values)
    return result


def _mean_lateral_deviation(a: np.ndarray, b: np.ndarray, y_samples: np.ndarray) -> float:
    """Mean |x_a(y) - x_b(y)| over the y samples within both lanes' y extents; NaN if fewer
    than two."""
    common = y_samples[
        (y_samples >= max(a[:, 1].min(), b[:, 1].min()))
        & (y_samples <= min(a[:, 1].max(), b[:, 1].max()))
    ]
    if len(common) < 2:
        return float("nan")
    return float(np.mean(np.abs(_x_at(a, common) - _x_at(b, common))))


def _x_at(lane: np.ndarray, y: np.ndarray) -> np.ndarray:
    order = np.argsort(lane[:, 1], kind="mergesort")
    return np.interp(y, lane[order, 1], lane[order, 0])


def _pairs_by_track(previous: Sequence[int], current: Sequence[int]) -> list[tuple[int, int]]:
    """(i, j) of lanes sharing a track id (the first lane of each id)."""
    first_current: dict[int, int] = {}
    for j, track in enumerate(current):
        first_current.setdefault(track, j)
    pairs, seen = [], set()
    for i, track in enumerate(previous):
        if track != NO_TRACK and track in first_current and track not in seen:
            pairs.append((i, first_current[track]))
            seen.add(track)
    return pairs


def _nearest_pairs(
    deviation: np.ndarray, rows: list[int], cols: list[int], gate: float
) -> list[tuple[int, int]]:
    """Greedy one-to-one pairs of the given rows and columns, smallest deviation first,
    below the gate."""
    candidates = sorted(
        (deviation[i, j], i, j) for i in rows for j in cols if deviation[i, j] < gate
    )
    pairs, used_rows, used_cols = [], set(), set()
    for _, i, j in candidates:
        if i not in used_rows and j not in used_cols:
            pairs.append((i, j))
            used_rows.add(i)
            used_cols.add(j)
    return pairs
