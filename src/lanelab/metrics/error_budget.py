"""Where a detector's F1 goes: each kind of error fixed with the ground truth, one at a time.

The OpenLane F1 says how many lanes a detector gets right, not why the others fail. TIDE
(Bolya et al., "TIDE: A General Toolbox for Identifying Object Detection Errors", ECCV 2020)
answers that for boxes by correcting one error type with the ground truth and measuring the
gain. This module does the same for 3D lanes. Each predicted lane is first *associated* with
the ground-truth lane it is about, more loosely than the metric matches them (the metric
rejects a lane that is right near the ego and wrong beyond; the association must not). Then
each fix rewrites the predictions and the frame is scored again by the metric itself:

- ``near positions``: the associated lanes' x and z where y <= the metric's close range are the
  ground truth's; beyond, each lane keeps its own shape, moved by its last near correction;
- ``far positions``: the same beyond the close range (to the last sample, with the long-range
  metric too), the near range left as predicted;
- ``positions``: both;
- ``extents``: each associated lane covers the samples its ground truth covers (where it
  ends, where it starts), extended straight past its own ends;
- ``missed lanes``: the ground-truth lanes no prediction is about are added;
- ``false lanes``: the predictions about no ground-truth lane are removed.

A fix's gain is the F1 a detector would gain from mastering that part alone; the gains need
not add up, since a lane can fail for two reasons. Positions are rewritten at the samples both
lanes cover; a predicted sample the ground truth does not cover moves with the nearest
rewritten one (the correction is interpolated linearly between them).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from lanelab.metrics.assignment import min_cost_assignment
from lanelab.metrics.openlane import (
    FrameResult,
    OpenLaneConfig,
    SampledLanes,
    evaluate_frames,
    evaluate_sampled,
    paired_frames,
    sample_ground_truth,
    sample_predictions,
    score_frames,
    summarize,
)
from lanelab.openlane.read import GroundTruthFrame, PredictionFrame

FIXES = ("near positions", "far positions", "positions", "extents", "missed lanes", "false lanes")
# Samples a prediction and its ground truth must share to be associated.
_MIN_COMMON_SAMPLES = 3
# The cost (mm) of a pair that may not be associated: dearer than all pairable ones of a frame together.
_UNPAIRABLE_MM = 10**7
# Samples at each end of a lane that set the straight line it is extended along.
_END_SAMPLES = 10


@dataclass(frozen=True)
class _Frame:
    """One frame at the y samples: ground truth, predictions, and the association: pairs
    (ground-truth row, prediction row), missed ground-truth rows, false prediction rows."""

    gt: SampledLanes
    pred: SampledLanes
    pairs: list[tuple[int, int]]
    missed: list[int]
    false: list[int]


def associate(
    gt: SampledLanes, pred: SampledLanes, config: OpenLaneConfig, max_distance: float
) -> list[tuple[int, int]]:
    """One-to-one (ground-truth row, prediction row) pairs of minimum total cost, the cost of a
    pair being its mean |x difference| over the close-range samples both cover (all common
    samples when fewer than three are close). Pairs costlier than max_distance (metres) or
    sharing fewer than three samples are left unpaired."""
    if len(gt.x) == 0 or len(pred.x) == 0:
        return []
    both = gt.visible[:, None] & pred.visible[None]  # (G, P, S)
    near = both & _close_samples(config)
    use = np.where((near.sum(-1) >= _MIN_COMMON_SAMPLES)[..., None], near, both)
    count = use.sum(-1)
    dx = np.abs(gt.x[:, None] - pred.x[None])
    cost = np.where(count >= _MIN_COMMON_SAMPLES, (dx * use).sum(-1) / np.maximum(count, 1), np.inf)
    # Every pair beyond max_distance costs the same: the assignment then pairs as many lanes as
    # it can, and among those pairings the closest (a solver pairs min(G, P) lanes in any case).
    pairable = cost <= max_distance
    millimetres = np.where(pairable, np.round(np.where(pairable, cost, 0) * 1000), _UNPAIRABLE_MM)
    return [(g, p) for g, p in min_cost_assignment(millimetres) if pairable[g, p]]


def error_budget(
    frames: Iterable[tuple[GroundTruthFrame, PredictionFrame]],
    config: OpenLaneConfig = OpenLaneConfig(),
    max_distance: float = 2.0,
) -> dict[str, dict[str, float | int]]:
    """The :func:`~lanelab.metrics.openlane.summarize` scores of the predictions as they are
    ("as predicted") and with each fix of :data:`FIXES`, over (ground truth, prediction)
    frames; max_distance: see :func:`associate`. Each entry also counts the associated,
    missed and false lanes (``associated``, ``missed``, ``false``)."""
    sampled = []
    for gt_frame, pred_frame in frames:
        gt = sample_ground_truth(gt_frame.lanes, gt_frame.visibility, gt_frame.categories, config)
        pred = sample_predictions(pred_frame.lanes, pred_frame.categories, config)
        pairs = associate(gt, pred, config, max_distance)
        missed = sorted(set(range(len(gt.x))) - {g for g, _ in pairs})
        false = sorted(set(range(len(pred.x))) - {p for _, p in pairs})
        sampled.append(_Frame(gt, pred, pairs, missed, false))
    counts = {
        "associated": sum(len(f.pairs) for f in sampled),
        "missed": sum(len(f.missed) for f in sampled),
        "false": sum(len(f.false) for f in sampled),
    }
    budget = {}
    for name in ("as predicted", *FIXES):
        fix = _FIX_STEPS[name]
        results = []
        for frame in sampled:  # the ground truth sampled once, scored against every fix
            lanes = _as_points(fix(frame, config), config)
            categories = [1] * len(lanes)  # the F1 does not look at them
            results.append(evaluate_sampled(frame.gt, sample_predictions(lanes, categories, config), config))
        budget[name] = {**summarize(results), **counts}
    return budget


def budget_table(budget: Mapping[str, Mapping[str, float | int]]) -> str:
    """A Markdown table of an :func:`error_budget`: one row per fix, its F1, the gain over the
    predictions as they are, precision / recall, x errors and how many lanes it predicts."""
    base = budget["as predicted"]["f1"]
    lines = [
        "| predictions | F1 (%) | gain (points) | P / R (%) | x close / far (m) | predicted lanes |",
        "|---|---:|---:|---|---|---:|",
    ]
    for name, s in budget.items():
        gain = "" if name == "as predicted" else f"{100 * (s['f1'] - base):+.1f}"
        lines.append(
            f"| {name} | {100 * s['f1']:.1f} | {gain} | {100 * s['precision']:.1f} / {100 * s['recall']:.1f} "
            f"| {s['x_error_close']:.3f} / {s['x_error_far']:.3f} | {s['pred_lanes']} |"
        )
    return "\n".join(lines) + "\n"


def gains_table(budgets: Mapping[str, Sequence[Mapping[str, Mapping[str, float | int]]]]) -> str:
    """A Markdown table comparing error budgets: one row per label (a model), its F1 as predicted
    and the points each fix gains, mean ± std over the label's budgets (seeds) when several."""
    fixes = [name for name in next(iter(budgets.values()))[0] if name != "as predicted"]
    lines = ["| predictions | F1 (%) | " + " | ".join(fixes) + " |", "|---|" + "---:|" * (len(fixes) + 1)]
    for label, runs in budgets.items():
        base = [run["as predicted"]["f1"] for run in runs]
        columns = [base] + [[run[fix]["f1"] - f1 for run, f1 in zip(runs, base)] for fix in fixes]
        cells = [_mean_std(values, signed=i > 0) for i, values in enumerate(columns)]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _mean_std(fractions: Sequence[float], signed: bool) -> str:
    """Percent (points when signed) of the mean, ± the sample std when there are several."""
    text = f"{100 * np.mean(fractions):{'+' if signed else ''}.1f}"
    return text + (f" ± {100 * np.std(fractions, ddof=1):.1f}" if len(fractions) > 1 else "")


def budget_counts(budget: Mapping[str, Mapping[str, float | int]]) -> str:
    """One sentence: how many predictions were associated, false, and lanes missed."""
    c = budget["as predicted"]
    return (
        f"{c['associated']} predicted lanes associated with a ground-truth lane, {c['false']} false; "
        f"{c['missed']} ground-truth lanes missed."
    )


def error_budget_of_files(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
    max_distance: float = 2.0,
) -> dict[str, dict[str, float | int]]:
    """:func:`error_budget` of OpenLane files, paired as the metric pairs them."""
    frames = ((gt, pred) for _, gt, pred in paired_frames(gt_dir, pred_dir, test_list))
    return error_budget(frames, config, max_distance)


def evaluate_with_budget(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
    budget: bool = True,
) -> tuple[list[tuple[str, FrameResult]], dict[str, dict[str, float | int]] | None]:
    """:func:`~lanelab.metrics.openlane.evaluate_frames` of OpenLane files and, with ``budget``,
    their :func:`error_budget` (else None). The files are read once and held for both."""
    if not budget:
        return evaluate_frames(gt_dir, pred_dir, test_list, config), None
    frames = list(paired_frames(gt_dir, pred_dir, test_list))
    return score_frames(frames, config), error_budget(((gt, pred) for _, gt, pred in frames), config)


# --- the fixes: each maps a frame to predicted lanes (x, z, covered) at the y samples ----------

_Lane = tuple[np.ndarray, np.ndarray, np.ndarray]  # x, z, covered: (S,) each
_Rewrite = Callable[[_Lane, _Lane, OpenLaneConfig], _Lane]  # (ground truth, prediction) -> prediction


def _row(lanes: SampledLanes, i: int) -> _Lane:
    return lanes.x[i], lanes.z[i], lanes.visible[i]


def _predicted(frame: _Frame, rows: Iterable[int] | None = None) -> list[_Lane]:
    rows = range(len(frame.pred.x)) if rows is None else rows
    return [_row(frame.pred, p) for p in rows]


def _fix_pairs(rewrite: _Rewrite) -> Callable[[_Frame, OpenLaneConfig], list[_Lane]]:
    """A fix that rewrites each associated prediction from its ground truth; the rest as is."""

    def fix(frame: _Frame, config: OpenLaneConfig) -> list[_Lane]:
        paired = [rewrite(_row(frame.gt, g), _row(frame.pred, p), config) for g, p in frame.pairs]
        return paired + _predicted(frame, frame.false)

    return fix


def _positions(part: str | None) -> _Rewrite:
    """Rewrite x and z of the samples of one part of the y range: "close" (the metric's close
    range), "far" (every sample beyond it, whatever further ranges the config has) or None (all)."""

    def rewrite(gt: _Lane, pred: _Lane, config: OpenLaneConfig) -> _Lane:
        (gx, gz, gv), (px, pz, pv) = gt, pred
        close = _close_samples(config)
        in_part = {"close": close, "far": ~close, None: np.ones_like(close)}[part]
        anchors = np.flatnonzero(gv & pv & in_part)
        if len(anchors) == 0:
            return px, pz, pv
        # A near fix carries its last correction on to the far samples; a far fix leaves the near ones.
        moved = pv & in_part if part == "far" else pv
        index = np.arange(len(px))
        x, z = px.copy(), pz.copy()
        x[moved] += np.interp(index[moved], anchors, gx[anchors] - px[anchors])
        z[moved] += np.interp(index[moved], anchors, gz[anchors] - pz[anchors])
        return x, z, pv

    return rewrite


def _extents(gt: _Lane, pred: _Lane, config: OpenLaneConfig) -> _Lane:
    """The prediction over the ground truth's samples, extended straight past its own ends."""
    (_, _, gv), (px, pz, pv) = gt, pred
    return _extend(px, pv), _extend(pz, pv), gv


def _extend(values: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """values (S,) known where covered: linear between, straight lines fitted to the first and
    last few covered samples beyond."""
    known = np.flatnonzero(covered)
    index = np.arange(len(values))
    out = np.interp(index, known, values[known])
    for end, beyond in ((known[:_END_SAMPLES], index < known[0]), (known[-_END_SAMPLES:], index > known[-1])):
        if len(end) >= 2:
            out[beyond] = np.polyval(np.polyfit(end, values[end], 1), index[beyond])
    return out


def _missed_added(frame: _Frame, config: OpenLaneConfig) -> list[_Lane]:
    return _predicted(frame) + [_row(frame.gt, g) for g in frame.missed]


def _false_removed(frame: _Frame, config: OpenLaneConfig) -> list[_Lane]:
    return _predicted(frame, sorted(p for _, p in frame.pairs))


_FIX_STEPS: dict[str, Callable[[_Frame, OpenLaneConfig], list[_Lane]]] = {
    "as predicted": lambda frame, config: _predicted(frame),
    "near positions": _fix_pairs(_positions("close")),
    "far positions": _fix_pairs(_positions("far")),
    "positions": _fix_pairs(_positions(None)),
    "extents": _fix_pairs(_extents),
    "missed lanes": _missed_added,
    "false lanes": _false_removed,
}


def _close_samples(config: OpenLaneConfig) -> np.ndarray:
    """(S,) bool: the y samples of the metric's close range."""
    close = np.zeros(len(config.y_samples), dtype=bool)
    close[dict(config.error_ranges)["close"]] = True
    return close


def _as_points(lanes: list[_Lane], config: OpenLaneConfig) -> list[np.ndarray]:
    """Lanes at the y samples -> (n, 3) point arrays of their covered samples, as a prediction
    file would hold them."""
    y = config.y_samples
    return [np.stack([x[v], y[v], z[v]], 1) for x, z, v in lanes if np.count_nonzero(v) >= 2]
