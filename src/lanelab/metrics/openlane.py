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

Two extensions of SparseLaneSTP (§5.1), off by default, are options of
:class:`OpenLaneConfig`: x/z errors over further y ranges (``extra_ranges``, with the
y-sampling extended, see :meth:`OpenLaneConfig.long_range`) and Vis-IoU (``vis_iou``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from lanelab.lanes import LEFT_CURBSIDE, RIGHT_CURBSIDE
from lanelab.metrics.assignment import min_cost_assignment
from lanelab.metrics.lane_sampling import overlaps_y_range, prune_to_box, resample_in_y
from lanelab.openlane.lists import read_test_list
from lanelab.openlane.read import (
    GroundTruthFrame,
    OpenLaneFormatError,
    PredictionFrame,
    read_ground_truth,
    read_prediction,
)
from lanelab.openlane.write import VISIBILITY_THRESHOLD


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
    # Extension: further splits of the far range, e.g. (100, 150) for the 40-100, 100-150
    # and 150-200 m errors of SparseLaneSTP's Table 5.
    extra_ranges: tuple[float, ...] = ()
    # Extension: Vis-IoU of the matched pairs (see _visibility_iou).
    vis_iou: bool = False
    # Predicted points of visibility at or below this are not part of the lane (lanelab's
    # OpenLane writer leaves them out of the JSON); also the "visible" cut of Vis-IoU.
    visibility_threshold: float = VISIBILITY_THRESHOLD

    @classmethod
    def long_range(cls) -> OpenLaneConfig:
        """SparseLaneSTP's long-range evaluation (§5.1): samples every metre from 3 to 200 m,
        errors over 0-40, 40-100, 100-150 and 150-200 m, and Vis-IoU.

        The prune window grows with the sampling range as in the official setting, where it
        reaches well past the last sample (200 m for 102 m): to 250 m, SparseLaneSTP's
        label range.
        """
        return cls(
            y_range=(3.0, 201.0),
            num_y_samples=198,
            prune_y_range=(0.0, 250.0),
            extra_ranges=(100.0, 150.0),
            vis_iou=True,
        )

    @property
    def y_samples(self) -> np.ndarray:
        """(S,) y values: S points from y_range[0] up to, not including, y_range[1]."""
        return np.linspace(*self.y_range, num=self.num_y_samples, endpoint=False)

    @property
    def error_ranges(self) -> list[tuple[str, slice]]:
        """(name, samples) of each error range: "close" (y <= close_range), "far" (up to
        the first extra range or the last sample), then "<lo>_<hi>" for each extra range."""
        y = self.y_samples
        # Quirk: "close" is the samples up to the first y > close_range (3 .. 40 m inclusive).
        edges = (self.close_range, *self.extra_ranges)
        splits = [int(np.searchsorted(y, edge, side="right")) for edge in edges]
        upper = (*self.extra_ranges[1:], y[-1])
        names = ["close", "far"] + [f"{lo:g}_{hi:g}" for lo, hi in zip(self.extra_ranges, upper)]
        bounds = [0, *splits, len(y)]
        return [(name, slice(a, b)) for name, a, b in zip(names, bounds[:-1], bounds[1:])]

    @property
    def pair_value_names(self) -> list[str]:
        """Names of the per-pair values a FrameResult holds: x_error_close, x_error_far,
        [x_error_100_150 ...], z_error_close, ..., [vis_iou]."""
        ranges = [name for name, _ in self.error_ranges]
        names = [f"{axis}_error_{name}" for axis in "xz" for name in ranges]
        return names + (["vis_iou"] if self.vis_iou else [])


# The scores detection_scores returns, fractions: the detection scores every table shows first.
DETECTION_SCORES = ("f1", "precision", "recall")
RATE_KEYS = (*DETECTION_SCORES, "category_accuracy")
# Per-frame counts that add up over frames (the keys of FrameResult.counts).
COUNT_KEYS = ("gt_lanes", "pred_lanes", "matched", "recall_tp", "precision_tp", "category_correct")


@dataclass(frozen=True)
class FrameResult:
    """Counts and per-pair values (errors, Vis-IoU) of one frame.

    gt_count / pred_count: lanes left after pruning (the recall / precision denominators).
    matched: accepted pairs (GT lane, predicted lane), as indices into the inputs of
    evaluate_frame, in increasing GT order.
    recall_tp / precision_tp: matched pairs covering >= ratio_threshold of the GT's / the
    prediction's visible samples. category_correct: matched pairs with the right category.
    pair_values: name (OpenLaneConfig.pair_value_names) -> (len(matched),) value of each
    matched pair, NaN where it has none: x_error_<range> / z_error_<range> the mean |dx| /
    |dz| over the samples of the range both lanes see; vis_iou (option) the pair's Vis-IoU.
    """

    gt_count: int
    pred_count: int
    matched: list[tuple[int, int]]
    recall_tp: int
    precision_tp: int
    category_correct: int
    pair_values: dict[str, np.ndarray]

    @property
    def counts(self) -> dict[str, int]:
        """The frame's counts under COUNT_KEYS."""
        return {
            "gt_lanes": self.gt_count,
            "pred_lanes": self.pred_count,
            "matched": len(self.matched),
            "recall_tp": self.recall_tp,
            "precision_tp": self.precision_tp,
            "category_correct": self.category_correct,
        }

    # The official errors by name.
    @property
    def x_error_close(self) -> np.ndarray:
        return self.pair_values["x_error_close"]

    @property
    def x_error_far(self) -> np.ndarray:
        return self.pair_values["x_error_far"]

    @property
    def z_error_close(self) -> np.ndarray:
        return self.pair_values["z_error_close"]

    @property
    def z_error_far(self) -> np.ndarray:
        return self.pair_values["z_error_far"]


@dataclass
class SampledLanes:
    """Lanes resampled at the y samples: x, z (L, S); visible (L, S) bool, the official
    per-sample visibility (within the lane's y extent and the x range); seen (L, S) bool,
    visible and seen by the lane's own visibility (Vis-IoU); category (L,) and index (L,),
    the lane's position in the caller's list."""

    x: np.ndarray
    z: np.ndarray
    visible: np.ndarray
    seen: np.ndarray
    category: np.ndarray
    index: np.ndarray


def evaluate_frame(
    gt_lanes: Sequence[np.ndarray],
    gt_visibility: Sequence[np.ndarray],
    gt_categories: Sequence[int],
    pred_lanes: Sequence[np.ndarray],
    pred_categories: Sequence[int],
    config: OpenLaneConfig = OpenLaneConfig(),
    pred_visibility: Sequence[np.ndarray] | None = None,
) -> FrameResult:
    """Score one frame.

    gt_lanes[i]: (N_i, 3) points in the evaluator's ground frame (x right, y forward, z up;
    see :func:`lanelab.openlane.ground_frame.ground_from_camera`), gt_visibility[i]: (N_i,),
    points with visibility <= 0 are dropped. pred_lanes[j]: (M_j, 3) or (M_j, 2) in the same
    frame (2 columns: z = 0). pred_visibility[j] (optional): (M_j,) in [0, 1]; points at or
    below config.visibility_threshold are dropped, so that the result equals that of a prediction
    file holding only the visible points. Official OpenLane predictions carry no visibility.
    """
    gt = sample_ground_truth(gt_lanes, gt_visibility, gt_categories, config)
    pred = sample_predictions(pred_lanes, pred_categories, config, pred_visibility)
    return evaluate_sampled(gt, pred, config)


def evaluate_sampled(gt: SampledLanes, pred: SampledLanes, config: OpenLaneConfig) -> FrameResult:
    """:func:`evaluate_frame` of lanes already sampled (:func:`sample_ground_truth`,
    :func:`sample_predictions`): for scoring one frame's ground truth against several predictions."""
    return _match_and_count(gt, pred, config.y_samples, config)


def sample_ground_truth(
    lanes: Sequence[np.ndarray], visibility: Sequence[np.ndarray], categories: Sequence[int], config: OpenLaneConfig
) -> SampledLanes:
    """Ground-truth lanes as :func:`evaluate_frame` scores them: points with visibility <= 0
    dropped, pruned and resampled at the config's y samples."""
    return _sample_lanes(lanes, visibility, categories, lambda v: v > 0, config)


def sample_predictions(
    lanes: Sequence[np.ndarray],
    categories: Sequence[int],
    config: OpenLaneConfig,
    visibility: Sequence[np.ndarray] | None = None,
) -> SampledLanes:
    """Predicted lanes as :func:`evaluate_frame` scores them (visibility: see there)."""
    if visibility is None:
        visibility = [np.ones(len(lane)) for lane in lanes]
    # Quirk: predictions skip the visibility step of the official code but get the same range
    # tests; dropping their invisible points here stands for leaving them out of the file.
    return _sample_lanes(lanes, visibility, categories, lambda v: v > config.visibility_threshold, config)


def _sample_lanes(
    lanes: Sequence[np.ndarray],
    visibility: Sequence[np.ndarray],
    categories: Sequence[int],
    keep: Callable[[np.ndarray], np.ndarray],
    config: OpenLaneConfig,
) -> SampledLanes:
    """Prune and resample lanes (N_i, 2 or 3) as the official evaluator does.

    A lane keeps its points whose visibility (N_i,) passes `keep`, needs two of them, a
    first point below the last sample and a last one beyond the first (overlaps_y_range),
    two points left in the prune box, and two visible samples.
    """
    y_samples = config.y_samples
    rows = []
    for index, (lane, vis, category) in enumerate(zip(lanes, visibility, categories)):
        lane, vis = np.asarray(lane, dtype=np.float64), np.asarray(vis, dtype=np.float64)
        points = lane[keep(vis)]
        if len(points) < 2 or not overlaps_y_range(points, y_samples[-1], y_samples[0]):
            continue
        points = prune_to_box(points, config.x_range, config.prune_y_range)
        if len(points) < 2:
            continue
        x, z, visible = resample_in_y(points, y_samples, config.x_range)
        if np.count_nonzero(visible) < 2:
            continue
        seen = visible
        if config.vis_iou:
            seen = visible & _seen_at(lane, vis, y_samples, config.visibility_threshold)
        rows.append((x, z, visible, seen, category, index))
    if not rows:
        empty, no_ids = np.zeros((0, len(y_samples))), np.zeros(0, dtype=np.int64)
        return SampledLanes(empty, empty, empty.astype(bool), empty.astype(bool), no_ids, no_ids)
    x, z, visible, seen, category, index = zip(*rows)
    return SampledLanes(
        np.stack(x), np.stack(z), np.stack(visible), np.stack(seen), np.array(category),
        np.array(index),
    )


def _seen_at(
    lane: np.ndarray, vis: np.ndarray, y_samples: np.ndarray, threshold: float
) -> np.ndarray:
    """(S,) bool: the lane's visibility (N,), linearly interpolated in y over all its points
    (N, >=2), is above threshold at each y sample. Unlike the official per-sample
    visibility, this sees occluded stretches inside the lane's extent."""
    order = np.argsort(lane[:, 1], kind="mergesort")
    return np.interp(y_samples, lane[order, 1], vis[order]) > threshold


def _match_and_count(
    gt: SampledLanes, pred: SampledLanes, y_samples: np.ndarray, config: OpenLaneConfig
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
    pair_values = {}
    for axis, d in (("x", dx[rows, cols]), ("z", dz[rows, cols])):
        for name, part in config.error_ranges:
            pair_values[f"{axis}_error_{name}"] = _mean_over(d, both[rows, cols], part)
    if config.vis_iou:
        pair_values["vis_iou"] = _visibility_iou(gt.seen[rows], pred.seen[cols])
    return FrameResult(
        gt_count=len(gt.x),
        pred_count=len(pred.x),
        matched=[(int(gt.index[g]), int(pred.index[p])) for g, p in matched],
        recall_tp=int(recall_tp),
        precision_tp=int(precision_tp),
        category_correct=int(category_correct),
        pair_values=pair_values,
    )


def _mean_over(d: np.ndarray, both: np.ndarray, part: slice) -> np.ndarray:
    """(K,) mean of d (K, S) over the samples of `part` both lanes see; NaN if none.

    Written as sum(d * mask) / count like the official code: a non-finite d at a sample
    only one lane sees (an extrapolation through duplicate y values) makes the mean NaN
    there too, and such a pair then drops out of the error averages as in the official.
    """
    count = both[..., part].sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (d[..., part] * both[..., part]).sum(axis=-1) / count, np.nan)


def _visibility_iou(gt_seen: np.ndarray, pred_seen: np.ndarray) -> np.ndarray:
    """(K,) Vis-IoU of K matched pairs from their seen masks (K, S); NaN if both are empty.

    SparseLaneSTP (§5.1) names the metric without a formula; this is the reading the paper's
    purpose asks for ("distinguishing visible lane segments from parts occluded ... a measure
    for start-end range detection"): over the y samples of the evaluation range, the IoU of
    the samples the GT lane is visible at (its per-point visibility, interpolated, within its
    official extent) and those the predicted lane is (likewise, from its predicted
    visibility; a prediction without visibility is visible over its extent). A missed start,
    end or occlusion gap lowers it; geometry does not (the errors measure that). It is
    averaged over matched pairs, like the errors. OpenLane prediction files carry no
    visibility and hold only visible points, so from files a predicted occlusion gap is
    bridged; fed with the model's visibility (OpenLaneMetric), it counts.
    """
    intersection = np.count_nonzero(gt_seen & pred_seen, axis=-1)
    union = np.count_nonzero(gt_seen | pred_seen, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, intersection / union, np.nan)


def detection_scores(counts: Mapping[str, int]) -> dict[str, float]:
    """f1, recall, precision and category_accuracy from counts summed over frames.

    recall = recall_tp / gt_lanes, precision = precision_tp / pred_lanes, category accuracy
    = category_correct / matched (all accepted pairs, true positive or not), F1 from recall
    and precision. A ratio with a zero denominator is 0 (the official 1e-6 epsilons only act
    there, and the numerator is then 0 too).
    """
    recall = _ratio(counts["recall_tp"], counts["gt_lanes"])
    precision = _ratio(counts["precision_tp"], counts["pred_lanes"])
    return {
        "f1": 2 * recall * precision / (recall + precision) if recall + precision else 0.0,
        "recall": recall,
        "precision": precision,
        "category_accuracy": _ratio(counts["category_correct"], counts["matched"]),
    }


def summarize(frames: Iterable[FrameResult]) -> dict[str, float | int]:
    """Aggregate frame results as the official evaluator does.

    Counts are summed over frames, then turned into scores by :func:`detection_scores`.
    Each pair value (errors, Vis-IoU) is the mean over all accepted pairs that have one
    (official -1 sentinels, NaN here); NaN if there is none. Also returns num_frames and
    the summed counts (COUNT_KEYS).
    """
    frames = list(frames)
    totals = {key: sum(f.counts[key] for f in frames) for key in COUNT_KEYS}
    result: dict[str, float | int] = dict(detection_scores(totals))
    names = frames[0].pair_values if frames else OpenLaneConfig().pair_value_names
    for name in names:
        values = np.concatenate([f.pair_values[name] for f in frames] or [np.zeros(0)])
        values = values[~np.isnan(values)]
        result[name] = float(values.mean()) if len(values) else float("nan")
    result["num_frames"] = len(frames)
    result.update(totals)
    return result


def _ratio(numerator: int, denominator: int) -> float:
    return numerator / denominator if denominator else 0.0


def evaluate_frames(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
) -> list[tuple[str, FrameResult]]:
    """(frame id, result) of every frame of a test list, in its order (a frame listed twice
    is scored twice, as officially). The frame id is the test-list line as
    :func:`read_test_list` reads it (relative JSON path), the key the scenario tables use.

    Pairing follows the official evaluator: each listed prediction is scored against the
    ground truth whose ``file_path`` equals the prediction's ``file_path`` (not the file at
    the same place); a prediction naming no listed ground truth is an error. Raises
    OpenLaneFormatError for unreadable or malformed files.
    """
    return score_frames(paired_frames(gt_dir, pred_dir, test_list), config)


def score_frames(
    frames: Iterable[tuple[str, GroundTruthFrame, PredictionFrame]], config: OpenLaneConfig = OpenLaneConfig()
) -> list[tuple[str, FrameResult]]:
    """(frame id, result) of (frame id, ground truth, prediction) frames, as :func:`paired_frames` gives them."""
    return [
        (rel, evaluate_frame(gt.lanes, gt.visibility, gt.categories, pred.lanes, pred.categories, config))
        for rel, gt, pred in frames
    ]


def paired_frames(
    gt_dir: str | os.PathLike[str], pred_dir: str | os.PathLike[str], test_list: str | os.PathLike[str]
) -> Iterator[tuple[str, GroundTruthFrame, PredictionFrame]]:
    """(frame id, ground truth, prediction) of every frame of a test list, paired as
    :func:`evaluate_frames` pairs them. Raises OpenLaneFormatError as it does."""
    relative_paths = read_test_list(test_list)
    ground_truths = {}
    for rel in relative_paths:
        frame = read_ground_truth(Path(gt_dir) / rel)
        ground_truths[frame.file_path] = frame  # Quirk: a repeated file_path keeps the last
    for rel in relative_paths:
        pred_path = Path(pred_dir) / rel
        pred = read_prediction(pred_path)
        gt = ground_truths.get(pred.file_path)
        if gt is None:
            raise OpenLaneFormatError(
                pred_path,
                f"file_path {pred.file_path!r} names no ground-truth frame of the test list",
            )
        yield rel, gt, pred


def evaluate(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
) -> dict[str, float | int]:
    """Evaluate a prediction directory against OpenLane ground truth, officially.

    test_list: text file of paths relative to gt_dir and pred_dir, one a line (image paths
    ending in .jpg name the .json beside them). Returns the :func:`summarize` dict: f1,
    recall, precision, category_accuracy (fractions), x/z_error_close/far (metres; more
    ranges and vis_iou with the extensions of the config), and the counts num_frames,
    gt_lanes, pred_lanes, matched, recall_tp, precision_tp, category_correct. Frames are
    paired as :func:`evaluate_frames` pairs them.
    """
    return summarize(result for _, result in evaluate_frames(gt_dir, pred_dir, test_list, config))
