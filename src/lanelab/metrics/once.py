"""The ONCE-3DLanes metric (F1, precision, recall, CD) as the official benchmark computes it.

Protocol learnt from the official evaluation code, once-3dlanes/once_3dlanes_benchmark
(``evaluation/eval_utils.py``, ``cfg/eval.json``), which PersFormer and LATR
(``utils/eval_3D_once.py``) ship unchanged and report with. Lanes are in the camera frame
(x right, y down, z forward, metres). For each frame and each score threshold
t = 0.10, 0.15, ..., 0.95:

1. GT lanes with at least 2 points count; predictions count if their score is > t.
   A lane whose first point is farther (z) than its second is reversed.
2. Every GT and predicted lane is drawn into a top-view image: x in [-10, 10] m across,
   z in [0, 50] m along, 0.05 m pixels, as 30-pixel-thick OpenCV line segments between
   consecutive points -- Quirk: only the points nearer than z = 10 m are drawn, whatever
   the image's 50 m. The pair cost is 1 - IoU of the two images (0 IoU if both are empty).
3. GT and predictions are matched one-to-one at minimum total cost (Munkres, with the
   ``munkres`` package's tie-breaking, see :mod:`lanelab.metrics.munkres`). Quirk: the
   configured IoU threshold (0.3) is never applied -- every matched pair, IoU 0 included,
   goes on to the distance test.
4. A matched pair is a true positive when the mean distance from 10 points along the GT
   lane (at 5 %, 15 %, ..., 95 % of its length) to the predicted polyline is below
   0.3 m -- the paper's unilateral chamfer distance. Quirk: shapely measures lengths and
   distances in the x-y plane, so z (depth) plays no part: it is the lateral and height
   offset that counts, and a GT lane that runs straight ahead has zero length in that
   plane (all 10 points are its first point).

Over frames, counts and distances are summed per threshold; precision = TP / predictions,
recall = TP / GT, F1 from both (NaN where a denominator is 0, as officially; F1 = 0 when
both are 0), and
CD = summed TP distances / (TP + 1e-5) (Quirk: the epsilon is always there). The official
code accumulates in float32 over 10 processes in file-system order; sums here are float64
(numbers agree to about 1e-7). Published tables report one threshold's row; best()
gives the row of highest F1.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import cv2
import numpy as np

from lanelab.json_files import LaneFileError, load_json_object, numeric_array, require, require_list
from lanelab.metrics.munkres import munkres_assignment
from lanelab.once.labels import lane_arrays

# Positions along a GT lane (fractions of its length) where the distance is measured.
_ALONG = np.arange(0.05, 1, 0.1)


@dataclass(frozen=True)
class OnceConfig:
    """The official settings (cfg/eval.json and the code's constants)."""

    side_range: tuple[float, float] = (-10.0, 10.0)  # top view, x (metres)
    forward_range: tuple[float, float] = (0.0, 50.0)  # top view, z (metres)
    resolution: float = 0.05  # metres a pixel
    line_width: int = 30  # pixels
    drawn_below_z: float = 10.0  # Quirk: only points nearer than this are drawn
    distance_threshold: float = 0.3  # metres, mean distance of a true positive
    # 0.10, 0.15, ..., 0.95, computed as the official k * 0.01
    score_thresholds: tuple[float, ...] = tuple(k * 0.01 for k in range(10, 100, 5))


@dataclass(frozen=True)
class OnceFrameResult:
    """One frame's counts, per score threshold (T = len(config.score_thresholds)).

    gt_count: GT lanes; pred_count (T,): predictions above each threshold; tp (T,): true
    positives; distance_sum (T,): sum of the true positives' mean distances (metres).
    """

    gt_count: int
    pred_count: np.ndarray
    tp: np.ndarray
    distance_sum: np.ndarray


def evaluate_once_frame(
    gt_lanes: Sequence[np.ndarray],
    pred_lanes: Sequence[np.ndarray],
    pred_scores: Sequence[float],
    config: OnceConfig = OnceConfig(),
) -> OnceFrameResult:
    """Score one frame: lanes (N_i, 3) in the camera frame (x right, y down, z forward)."""
    gt = [_near_first(lane) for lane in gt_lanes if len(lane) >= 2]
    pred = [_near_first(lane) for lane in pred_lanes]
    iou = _top_view_iou(gt, pred, config)
    distances: dict[tuple[int, int], float] = {}  # cached over thresholds
    T = len(config.score_thresholds)
    pred_count, tp, distance_sum = np.zeros(T, np.int64), np.zeros(T, np.int64), np.zeros(T)
    for t, threshold in enumerate(config.score_thresholds):
        kept = [j for j, score in enumerate(pred_scores) if float(score) > threshold]
        pred_count[t] = len(kept)
        if not gt or not kept:
            continue
        cost = [[1.0 - iou[i][j] for j in kept] for i in range(len(gt))]
        for i, k in munkres_assignment(cost):
            j = kept[k]
            if (i, j) not in distances:
                distances[i, j] = _mean_distance(gt[i], pred[j])
            if distances[i, j] < config.distance_threshold:
                tp[t] += 1
                distance_sum[t] += distances[i, j]
    return OnceFrameResult(len(gt), pred_count, tp, distance_sum)


def summarize_once(
    frames: Iterable[OnceFrameResult], config: OnceConfig = OnceConfig()
) -> list[dict[str, float | int]]:
    """One row per score threshold: score_threshold, f1, precision, recall, cd (metres),
    gt_lanes, pred_lanes, tp, and num_frames."""
    frames = list(frames)
    T = len(config.score_thresholds)
    gt = sum(f.gt_count for f in frames)
    pred = np.sum([f.pred_count for f in frames], axis=0) if frames else np.zeros(T, int)
    tp = np.sum([f.tp for f in frames], axis=0) if frames else np.zeros(T, int)
    distance = np.sum([f.distance_sum for f in frames], axis=0) if frames else np.zeros(T)
    rows = []
    for t, threshold in enumerate(config.score_thresholds):
        precision = tp[t] / pred[t] if pred[t] else float("nan")
        recall = tp[t] / gt if gt else float("nan")
        # 0 where precision and recall are both 0 (the official 0 / 0 gives NaN)
        f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
        rows.append({
            "score_threshold": threshold,
            "f1": float(f1),
            "precision": float(precision),
            "recall": float(recall),
            "cd": float(distance[t] / (tp[t] + 1e-5)),
            "gt_lanes": gt,
            "pred_lanes": int(pred[t]),
            "tp": int(tp[t]),
            "num_frames": len(frames),
        })
    return rows


def best(rows: Sequence[dict[str, float | int]]) -> dict[str, float | int]:
    """The row of highest F1 (the first of equals; NaN F1 never wins)."""
    return max(rows, key=lambda row: -1.0 if row["f1"] != row["f1"] else row["f1"])


def evaluate_once(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    config: OnceConfig = OnceConfig(),
) -> list[dict[str, float | int]]:
    """Evaluate a prediction directory against ONCE-3DLanes ground truth.

    Every ``*.json`` under gt_dir (``<sequence>/cam01/<frame>.json``) is scored against the
    file at the same relative path under pred_dir. Returns :func:`summarize_once` rows;
    raises LaneFileError for a missing, unreadable or malformed file.
    """
    frames = []
    for gt_path in sorted(Path(gt_dir).rglob("*.json")):
        pred_path = Path(pred_dir) / gt_path.relative_to(gt_dir)
        if not pred_path.is_file():
            raise LaneFileError(pred_path, f"no prediction for ground-truth file {gt_path}")
        lanes, scores = read_once_prediction(pred_path)
        frames.append(evaluate_once_frame(read_once_ground_truth(gt_path), lanes, scores, config))
    return summarize_once(frames, config)


def read_once_ground_truth(path: str | os.PathLike[str]) -> list[np.ndarray]:
    """GT lanes (N_i, 3) of a ONCE-3DLanes label file: ``{"lanes": [[[x, y, z], ...], ...],
    "calibration": ...}``. Lanes of fewer than 2 points are left out, as officially."""
    return lane_arrays(load_json_object(path), path)


def read_once_prediction(path: str | os.PathLike[str]) -> tuple[list[np.ndarray], list[float]]:
    """Predicted lanes (N_i, 3) and scores of a prediction file:
    ``{"lanes": [{"points": [[x, y, z], ...], "score": s}, ...]}``."""
    lanes, scores = [], []
    for i, lane in enumerate(require_list(load_json_object(path), "lanes", path)):
        where = f"lanes[{i}]"
        points = numeric_array(require(lane, "points", path, where), (None, 3), f"{where}.points",
                               path)
        if len(points) < 2:
            raise LaneFileError(path, f"{where}.points needs at least 2 points, got {len(points)}")
        score = require(lane, "score", path, where)
        try:
            scores.append(float(score))
        except (TypeError, ValueError):
            raise LaneFileError(path, f"{where}.score must be a number, got {score!r}") from None
        lanes.append(points)
    return lanes, scores


def _near_first(lane: np.ndarray) -> np.ndarray:
    """The lane reversed if its first point is farther (z) than its second (official)."""
    lane = np.asarray(lane, dtype=np.float64)
    return lane[::-1] if lane[0, 2] > lane[1, 2] else lane


def _top_view_iou(
    gt: list[np.ndarray], pred: list[np.ndarray], config: OnceConfig
) -> list[list[float]]:
    """[i][j] IoU of the top-view images of GT lane i and predicted lane j."""
    if not gt or not pred:
        return [[0.0] * len(pred) for _ in gt]
    masks = np.stack([_top_view(lane, config) for lane in gt + pred])
    rows = np.flatnonzero(masks.any(axis=(0, 2)))  # crop to the drawn rows
    masks = masks[:, rows].reshape(len(masks), -1).astype(np.float32)
    # Pixel counts stay far below 2**24, so these float32 sums are exact integers.
    intersection = (masks[: len(gt)] @ masks[len(gt) :].T).astype(np.float64)
    counts = masks.sum(axis=1, dtype=np.float64)
    union = counts[: len(gt), None] + counts[None, len(gt) :] - intersection
    with np.errstate(invalid="ignore", divide="ignore"):
        # pixels / pixels rounds like the official (255 * pixels) / (255 * pixels)
        return np.where(union > 0, intersection / union, 0.0).tolist()


def _top_view(lane: np.ndarray, config: OnceConfig) -> np.ndarray:
    """(H, W) bool top-view image of a lane (official Bev_Projector.proj_oneline_zx)."""
    (left, right), (near, far), res = config.side_range, config.forward_range, config.resolution
    image = np.zeros((int((far - near) / res), int((right - left) / res)), dtype=np.uint8)
    drawn = lane[lane[:, 2] < config.drawn_below_z]
    u = (drawn[:, 0] / res).astype(np.int32) + int(right / res)
    v = (-drawn[:, 2] / res).astype(np.int32) + int(far / res)
    for k in range(len(drawn) - 1):
        cv2.line(image, (int(u[k]), int(v[k])), (int(u[k + 1]), int(v[k + 1])), 255,
                 config.line_width)
    return image > 0


def _mean_distance(gt: np.ndarray, pred: np.ndarray) -> float:
    """Mean x-y distance from 10 points along the GT polyline to the predicted polyline
    (official cal_mean_dist, with shapely's 2-D interpolate and distance)."""
    total = 0.0
    length = _length_2d(gt)
    for fraction in _ALONG:
        total += _distance_to_polyline(_point_along(gt, fraction * length), pred)
    return total / len(_ALONG)


def _length_2d(line: np.ndarray) -> float:
    total = 0.0
    for k in range(1, len(line)):
        dx, dy = line[k, 0] - line[k - 1, 0], line[k, 1] - line[k - 1, 1]
        total += np.sqrt(dx * dx + dy * dy)
    return total


def _point_along(line: np.ndarray, distance: float) -> tuple[float, float]:
    """(x, y) at a 2-D distance along the polyline (GEOS LengthIndexedLine.extractPoint)."""
    if distance <= 0.0:
        return line[0, 0], line[0, 1]
    walked = 0.0
    for k in range(1, len(line)):
        (x0, y0), (x1, y1) = line[k - 1, :2], line[k, :2]
        dx, dy = x1 - x0, y1 - y0
        segment = np.sqrt(dx * dx + dy * dy)
        if walked + segment > distance:
            fraction = (distance - walked) / segment
            if fraction <= 0.0:
                return x0, y0
            if fraction >= 1.0:
                return x1, y1
            return (x1 - x0) * fraction + x0, (y1 - y0) * fraction + y0
        walked += segment
    return line[-1, 0], line[-1, 1]


def _distance_to_polyline(point: tuple[float, float], line: np.ndarray) -> float:
    """Smallest x-y distance from a point to the segments of a polyline (GEOS
    Distance::pointToSegment)."""
    px, py = point
    best = np.inf
    for k in range(1, len(line)):
        (ax, ay), (bx, by) = line[k - 1, :2], line[k, :2]
        if ax == bx and ay == by:
            d = np.sqrt((px - ax) ** 2 + (py - ay) ** 2)
        else:
            len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
            r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / len2
            if r <= 0.0:
                d = np.sqrt((px - ax) ** 2 + (py - ay) ** 2)
            elif r >= 1.0:
                d = np.sqrt((px - bx) ** 2 + (py - by) ** 2)
            else:
                s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / len2
                d = abs(s) * np.sqrt(len2)
        best = min(best, d)
    return float(best)
