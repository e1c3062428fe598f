"""The OpenLane 3D-lane metric (F1, recall, precision, category accuracy, x/z errors).

A clean-room implementation that reproduces the official evaluator's numbers
(OpenDriveLab/OpenLane, ``eval/LANE_evaluation/lane3d/eval_3D_lane.py``: ``LaneEval.bench``
for one frame and ``LaneEval.bench_one_submit`` for a directory), quirks included. The
version reproduced is the current one (shared with PersFormer's ``utils/eval_3D_lane.py``):
predictions are range-pruned like the GT, samples neither lane sees cost nothing, lanes
need two visible samples, pairs without a common sample in a range get no error there (the
official -1 sentinel), and the 1e-6 epsilons only guard zero denominators. Each quirk is
marked "Quirk" where it is reproduced.

Per frame (:func:`evaluate_frame`): lanes are pruned, resampled at 100 y values (3 m ..
102 m, 1 m apart), GT and predictions are matched one-to-one at minimum total distance, and
a matched pair counts towards recall / precision when at least 75 % of the GT's / the
prediction's visible samples lie within 1.5 m. Over frames (:func:`summarize`), counts are
summed before dividing, and errors are averaged over all matched pairs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from lanelab.metrics.assignment import min_cost_assignment
from lanelab.metrics.lane_sampling import overlaps_y_range, prune_to_box, resample_in_y
from lanelab.metrics.openlane_io import (
    OpenLaneFormatError,
    read_ground_truth,
    read_prediction,
    read_test_list,
)

# Curbside ids (DESIGN.md "Lane categories").
LEFT_CURBSIDE, RIGHT_CURBSIDE = 20, 21


@dataclass(frozen=True)
class OpenLaneConfig:
    """Evaluation region and thresholds; the defaults are the official ones."""

    x_range: tuple[float, float] = (-10.0, 10.0)
    y_range: tuple[float, float] = (3.0, 103.0)
    num_y_samples: int = 100
    dist_threshold: float = 1.5  # metres, per sample
    ratio_threshold: float = 0.75  # share of visible samples within dist_threshold
    close_range: float = 40.0  # metres, the close / far split of the errors
    # Official hard-coded y window of prune_3d_lane_by_range (points kept strictly inside).
    prune_y_range: tuple[float, float] = (0.0, 200.0)

    @property
    def y_samples(self) -> np.ndarray:
        """(S,) y values: S points from y_range[0] up to, not including, y_range[1]."""
        return np.linspace(*self.y_range, num=self.num_y_samples, endpoint=False)


@dataclass(frozen=True)
class FrameResult:
    """Counts and per-pair errors of one frame.

    gt_count / pred_count: lanes left after pruning (the recall / precision denominators).
    matched: accepted pairs (GT lane, predicted lane), as indices into the inputs of
    evaluate_frame, in increasing GT order.
    recall_tp / precision_tp: matched pairs covering >= ratio_threshold of the GT's / the
    prediction's visible samples. category_correct: matched pairs with the right category.
    x_error_close ... z_error_far: (len(matched),) mean |dx| / |dz| of each matched pair over
    the samples both lanes see, NaN where they see none in that range.
    """

    gt_count: int
    pred_count: int
    matched: list[tuple[int, int]]
    recall_tp: int
    precision_tp: int
    category_correct: int
    x_error_close: np.ndarray
    x_error_far: np.ndarray
    z_error_close: np.ndarray
    z_error_far: np.ndarray


@dataclass
class _Sampled:
    """Lanes resampled at the y samples: x, z (L, S), visible (L, S) bool; category (L,) and
    index (L,), the lane's position in the caller's list."""

    x: np.ndarray
    z: np.ndarray
    visible: np.ndarray
    category: np.ndarray
    index: np.ndarray


def evaluate_frame(
    gt_lanes: Sequence[np.ndarray],
    gt_visibility: Sequence[np.ndarray],
    gt_categories: Sequence[int],
    pred_lanes: Sequence[np.ndarray],
    pred_categories: Sequence[int],
    config: OpenLaneConfig = OpenLaneConfig(),
) -> FrameResult:
    """Score one frame.

    gt_lanes[i]: (N_i, 3) points in the evaluator's ground frame (x right, y forward, z up;
    see :func:`lanelab.metrics.openlane_io.ground_from_camera`), gt_visibility[i]: (N_i,),
    points with visibility <= 0 are dropped. pred_lanes[j]: (M_j, 3) or (M_j, 2) in the same
    frame (2 columns: z = 0).
    """
    y_samples = config.y_samples
    gt_kept = []
    for i, (lane, vis, cat) in enumerate(zip(gt_lanes, gt_visibility, gt_categories)):
        lane = np.asarray(lane, dtype=np.float64)[np.asarray(vis) > 0]
        if len(lane) > 1 and overlaps_y_range(lane, y_samples[-1], y_samples[0]):
            gt_kept.append((prune_to_box(lane, config.x_range, config.prune_y_range), cat, i))
    pred_kept = []
    for j, (lane, cat) in enumerate(zip(pred_lanes, pred_categories)):
        lane = np.asarray(lane, dtype=np.float64)
        # Quirk: predictions skip the visibility step but get the same range tests.
        if overlaps_y_range(lane, y_samples[-1], y_samples[0]):
            pred_kept.append((prune_to_box(lane, config.x_range, config.prune_y_range), cat, j))
    gt = _resample(gt_kept, y_samples, config)
    pred = _resample(pred_kept, y_samples, config)
    return _match_and_count(gt, pred, y_samples, config)


def _resample(
    lanes: list[tuple[np.ndarray, int, int]], y_samples: np.ndarray, config: OpenLaneConfig
) -> _Sampled:
    """Resample (points, category, index) lanes with >= 2 points; keep those with >= 2
    visible samples."""
    rows = [
        (*resample_in_y(points, y_samples, config.x_range), cat, index)
        for points, cat, index in lanes
        if len(points) > 1
    ]
    rows = [row for row in rows if np.count_nonzero(row[2]) > 1]
    if not rows:
        empty, no_ids = np.zeros((0, len(y_samples))), np.zeros(0, dtype=np.int64)
        return _Sampled(empty, empty, empty.astype(bool), no_ids, no_ids)
    x, z, visible, category, index = zip(*rows)
    return _Sampled(np.stack(x), np.stack(z), np.stack(visible), np.array(category), np.array(index))


def _match_and_count(
    gt: _Sampled, pred: _Sampled, y_samples: np.ndarray, config: OpenLaneConfig
) -> FrameResult:
    # All GT x pred pairs at once: (G, P, S), samples contiguous in the last axis so that
    # every sum below adds the same numbers in the same order as the official 1-D sums.
    dx = np.abs(gt.x[:, None, :] - pred.x[None, :, :])
    dz = np.abs(gt.z[:, None, :] - pred.z[None, :, :])
    both = gt.visible[:, None, :] & pred.visible[None, :, :]
    neither = ~gt.visible[:, None, :] & ~pred.visible[None, :, :]
    dist = np.sqrt(dx**2 + dz**2)
    dist[neither] = 0.0  # samples neither lane covers cost nothing
    dist[~both & ~neither] = config.dist_threshold  # samples only one lane covers
    close_points = np.count_nonzero((dist < config.dist_threshold) & both, axis=-1)
    total = dist.sum(axis=-1)
    # Quirk: the cost is the summed distance truncated to an integer, except that a sum in
    # (0, 1) costs 1 -- ties between candidates that differ by less than 1 m are common.
    cost = np.where((total > 0) & (total < 1), 1, np.trunc(total)).astype(np.int64)

    # Quirk: "close" is the samples up to the first y > close_range (3 .. 40 m inclusive).
    split = int(np.argmax(y_samples > config.close_range))
    errors = [
        _mean_over(d, both, part)
        for d in (dx, dz)
        for part in (slice(None, split), slice(split, None))
    ]

    matched = [
        (g, p)
        for g, p in min_cost_assignment(cost)
        if cost[g, p] < config.dist_threshold * len(y_samples)
    ]
    gt_visible = gt.visible.sum(axis=-1)
    pred_visible = pred.visible.sum(axis=-1)
    recall_tp = precision_tp = category_correct = 0
    for g, p in matched:
        recall_tp += close_points[g, p] / gt_visible[g] >= config.ratio_threshold
        precision_tp += close_points[g, p] / pred_visible[p] >= config.ratio_threshold
        # Quirk: a left-curbside prediction also counts as correct on a right-curbside GT
        # (not the other way round).
        pred_cat, gt_cat = pred.category[p], gt.category[g]
        category_correct += pred_cat == gt_cat or (
            pred_cat == LEFT_CURBSIDE and gt_cat == RIGHT_CURBSIDE
        )
    rows = np.array([g for g, _ in matched], dtype=np.int64)
    cols = np.array([p for _, p in matched], dtype=np.int64)
    x_close, x_far, z_close, z_far = (e[rows, cols] for e in errors)
    return FrameResult(
        gt_count=len(gt.x),
        pred_count=len(pred.x),
        matched=[(int(gt.index[g]), int(pred.index[p])) for g, p in matched],
        recall_tp=int(recall_tp),
        precision_tp=int(precision_tp),
        category_correct=int(category_correct),
        x_error_close=x_close,
        x_error_far=x_far,
        z_error_close=z_close,
        z_error_far=z_far,
    )


def _mean_over(d: np.ndarray, both: np.ndarray, part: slice) -> np.ndarray:
    """(G, P) mean of d (G, P, S) over the samples of `part` both lanes see; NaN if none.

    Written as sum(d * mask) / count like the official code: a non-finite d at a sample
    only one lane sees (an extrapolation through duplicate y values) makes the mean NaN
    there too, and such a pair then drops out of the error averages as in the official.
    """
    count = both[..., part].sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (d[..., part] * both[..., part]).sum(axis=-1) / count, np.nan)


def summarize(frames: Iterable[FrameResult]) -> dict[str, float | int]:
    """Aggregate frame results as the official evaluator does.

    Counts are summed over frames, then recall = recall_tp / gt_lanes, precision =
    precision_tp / pred_lanes, category accuracy = category_correct / matched (all accepted
    pairs, true positive or not), F1 from recall and precision. A ratio with a zero
    denominator is 0 (the official 1e-6 epsilons only act there, and the numerator is then
    0 too). Errors are the mean over all accepted pairs that see a sample in the range
    (official -1 sentinels, NaN here); NaN if there is none.
    """
    frames = list(frames)
    totals = {
        "gt_lanes": sum(f.gt_count for f in frames),
        "pred_lanes": sum(f.pred_count for f in frames),
        "matched": sum(len(f.matched) for f in frames),
        "recall_tp": sum(f.recall_tp for f in frames),
        "precision_tp": sum(f.precision_tp for f in frames),
        "category_correct": sum(f.category_correct for f in frames),
    }
    recall = _ratio(totals["recall_tp"], totals["gt_lanes"])
    precision = _ratio(totals["precision_tp"], totals["pred_lanes"])
    f1 = 2 * recall * precision / (recall + precision) if recall + precision else 0.0
    result: dict[str, float | int] = {
        "f1": f1,
        "recall": recall,
        "precision": precision,
        "category_accuracy": _ratio(totals["category_correct"], totals["matched"]),
    }
    for name in ("x_error_close", "x_error_far", "z_error_close", "z_error_far"):
        values = np.concatenate([getattr(f, name) for f in frames] or [np.zeros(0)])
        values = values[~np.isnan(values)]
        result[name] = float(values.mean()) if len(values) else float("nan")
    result["num_frames"] = len(frames)
    result.update(totals)
    return result


def _ratio(numerator: int, denominator: int) -> float:
    return numerator / denominator if denominator else 0.0


def evaluate(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
) -> dict[str, float | int]:
    """Evaluate a prediction directory against OpenLane ground truth, officially.

    test_list: text file of paths relative to gt_dir and pred_dir, one a line (image paths
    ending in .jpg name the .json beside them). Returns the :func:`summarize` dict: f1,
    recall, precision, category_accuracy (fractions), x/z_error_close/far (metres), and the
    counts num_frames, gt_lanes, pred_lanes, matched, recall_tp, precision_tp,
    category_correct.

    Pairing follows the official evaluator: each listed prediction is scored against the
    ground truth whose ``file_path`` equals the prediction's ``file_path`` (not the file at
    the same place); a prediction naming no listed ground truth is an error. Raises
    OpenLaneFormatError for unreadable or malformed files.
    """
    relative_paths = read_test_list(test_list)
    ground_truths = {}
    for rel in relative_paths:
        frame = read_ground_truth(Path(gt_dir) / rel)
        ground_truths[frame.file_path] = frame  # Quirk: a repeated file_path keeps the last
    results = []
    for rel in relative_paths:
        pred_path = Path(pred_dir) / rel
        pred = read_prediction(pred_path)
        gt = ground_truths.get(pred.file_path)
        if gt is None:
            raise OpenLaneFormatError(
                pred_path,
                f"file_path {pred.file_path!r} names no ground-truth frame of the test list",
            )
        results.append(
            evaluate_frame(
                gt.lanes, gt.visibility, gt.categories, pred.lanes, pred.categories, config
            )
        )
    return summarize(results)
