"""The blind prior: the score of a prediction that looks at no image, beside every model's.

A detector that scores below the blind prior has learnt less from the camera than the
training labels' average layout already says. The prior is the mean lane layout of a clip
store's training split, straight and flat, predicted identically for every frame:

1. For every labeled frame of the split, each lane's **lateral offset** is its mean x over
   :data:`NEAR_Y` (5 <= y <= 20 m ahead: the label polyline, occluded parts included,
   interpolated every metre inside its own y extent). Lanes that do not reach that window
   (a merge or split far ahead) have no offset and are left out.
2. The lanes left of the ego (offset < 0) are ranked outward 1, 2, ... by offset, and those
   right of it (offset >= 0) likewise: rank k on a side is a **slot** (``L1`` the nearest line
   on the left, ``R2`` the second on the right, ...). Ranks are geometric: an occluded lane
   still holds its rank.
3. A slot counts the lanes of its rank that the metric can see, those with two or more
   points of visibility above :data:`VISIBLE` inside the metric's x and y ranges (the ground
   truth the evaluation writes keeps only the visible points). The slot is kept when that happens in at
   least half of the labeled frames (:data:`MIN_PRESENCE`); its lane is then
   ``x`` = the mean offset of those lanes, ``category`` = their most common OpenLane category
   (the smallest id on a tie), and ``y_start`` / ``y_end`` = the medians of their visible y
   ranges (first and last visible point inside the metric's ranges); z = 0.

It is deterministic (same store, same numbers) and reads only the ``labeled`` and ``lanes``
columns of the clip files (:meth:`lanelab.store.ClipStore.read_labels`), not
the images.

The prior is scored with the OpenLane metric of :mod:`lanelab.metrics.openlane` against the
very ground-truth files the model's report is scored on (:func:`score_blind_prior`, which
gives what :func:`~lanelab.metrics.openlane.evaluate` gives on the files of
:func:`write_blind_prior_predictions`), and shown as a reference row of the report
(:func:`blind_prior_reference`, :class:`lanelab.evaluation.report.Reference`).
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from lanelab.data_paths import path_inside
from lanelab.evaluation.report import ERROR_BUDGET_KEY, Reference, build_reference
from lanelab.metrics.error_budget import error_budget as budget_of
from lanelab.metrics.openlane import FrameResult, OpenLaneConfig, evaluate_frame
from lanelab.metrics.scenarios import Scenario
from lanelab.openlane.lists import read_test_list
from lanelab.openlane.read import GroundTruthFrame, PredictionFrame, read_ground_truth
from lanelab.openlane.write import write_json

NAME = "blind prior"  # the row label in reports and tables
NEAR_Y = (5.0, 20.0)  # metres ahead: the window of a lane's lateral offset
VISIBLE = 0.5  # label visibility above which a point is visible (lanelab.data.targets.VISIBLE)
MIN_PRESENCE = 0.5  # share of labeled frames in which a slot's lane must be seen to be kept


class BlindPriorError(ValueError):
    """No blind prior can be computed from this store (the message says why)."""


@dataclass(frozen=True)
class PriorLane:
    """One lane of the blind prior: straight, flat (z = 0), at lateral offset x (metres, x
    right) from y_start to y_end (metres ahead), of OpenLane category id ``category``.

    side: "left" or "right" of the ego; rank: 1 for the nearest line on that side.
    presence: share of the labeled frames in which a lane of this slot was seen.
    """

    side: str
    rank: int
    x: float
    category: int
    y_start: float
    y_end: float
    presence: float

    @property
    def slot(self) -> str:
        """"L1", "R2", ...: side and rank."""
        return f"{self.side[0].upper()}{self.rank}"


@dataclass(frozen=True)
class BlindPrior:
    """The mean lane layout of a store's split (see the module): lanes left to right.

    store, split: where it comes from; num_labeled_frames: the frames it averages.
    """

    lanes: tuple[PriorLane, ...]
    store: str
    split: str
    num_labeled_frames: int

    def prediction_lanes(self, y_step: float = 1.0) -> tuple[list[np.ndarray], list[int]]:
        """The prior as predicted lanes: points (N, 3) every y_step metres from y_start to
        y_end (both included), x constant, z = 0; and their categories."""
        lanes = []
        for lane in self.lanes:
            count = max(2, int(np.ceil((lane.y_end - lane.y_start) / y_step - 1e-9)) + 1)
            y = np.linspace(lane.y_start, lane.y_end, count)
            lanes.append(np.stack([np.full_like(y, lane.x), y, np.zeros_like(y)], axis=1))
        return lanes, [lane.category for lane in self.lanes]

    def prediction_json(self, file_path: str) -> dict[str, Any]:
        """An OpenLane prediction file of the prior for the frame ``file_path``."""
        lanes, categories = self.prediction_lanes()
        return {
            "file_path": file_path,
            "lane_lines": [{"xyz": points.tolist(), "category": category}
                           for points, category in zip(lanes, categories)],
        }  # fmt: skip


def compute_blind_prior(
    store: str | os.PathLike[str],
    split: str = "train",
    config: OpenLaneConfig = OpenLaneConfig(),
) -> BlindPrior:
    """The blind prior of a clip store's split (see the module), for the metric of config: a
    lane is seen where it has visible points inside its x and y ranges, and the visible y
    ranges are clipped to its y range.

    Raises BlindPriorError, naming the store, when it is no clip store or its split has no
    labeled frame.
    """
    # The clip store's package brings torch along: imported only when a prior is computed.
    from lanelab.store import ClipStore, ManifestError

    try:
        clips = ClipStore(store)
        entries = clips.clips_in(split)
    except (ManifestError, ValueError) as err:
        raise BlindPriorError(str(err)) from None
    if not entries:
        raise BlindPriorError(f"{store}: no {split} clips")

    near = np.arange(NEAR_Y[0], NEAR_Y[1] + 0.5, 1.0)
    seen_by_slot: dict[tuple[str, int], list[tuple[float, int, float, float]]] = {}
    num_labeled = 0
    for entry in entries:
        for labeled, lanes in clips.read_labels(entry.clip_id):
            if not labeled:
                continue
            num_labeled += 1
            ranked = {"left": [], "right": []}
            for lane in lanes:
                offset = _near_offset(lane.points, near)
                if offset is not None:
                    ranked["left" if offset < 0 else "right"].append((abs(offset), offset, lane))
            for side, members in ranked.items():
                # Outward from the ego; ties (never in practice) by track id, so the order is fixed.
                members.sort(key=lambda member: (member[0], member[2].track_id))
                for rank, (_, offset, lane) in enumerate(members, start=1):
                    extent = _visible_extent(lane.points, lane.visibility, config)
                    if extent is not None:
                        seen_by_slot.setdefault((side, rank), []).append((offset, lane.category, *extent))
    if num_labeled == 0:
        raise BlindPriorError(f"{store}: no labeled frame in the {split} split")

    lanes = []
    for (side, rank), seen in seen_by_slot.items():
        presence = len(seen) / num_labeled
        if presence < MIN_PRESENCE:
            continue
        offsets, categories, starts, ends = zip(*seen)
        counts = Counter(categories)
        category = min(counts, key=lambda c: (-counts[c], c))
        y_start, y_end = float(np.median(starts)), float(np.median(ends))
        lanes.append(PriorLane(side, rank, float(np.mean(offsets)), int(category), y_start, y_end, presence))
    lanes.sort(key=lambda lane: lane.x)
    return BlindPrior(tuple(lanes), str(store), split, num_labeled)


def _near_offset(points: np.ndarray, near: np.ndarray) -> float | None:
    """A lane's mean x at the near y values (S,) inside its y extent; None if none is."""
    if len(points) == 0:
        return None
    y = points[:, 1]
    inside = near[(near >= y.min()) & (near <= y.max())]
    if len(inside) == 0:
        return None
    order = np.argsort(y, kind="mergesort")
    return float(np.mean(np.interp(inside, y[order], points[order, 0])))


def _visible_extent(points: np.ndarray, visibility: np.ndarray, config: OpenLaneConfig) -> tuple[float, float] | None:
    """(first, last) y of a lane's visible points inside the metric's x and y ranges; None
    unless two points are there (the metric needs two)."""
    x, y = points[:, 0], points[:, 1]
    (x_low, x_high), (y_low, y_high) = config.x_range, config.y_range
    y = y[(visibility > VISIBLE) & (x >= x_low) & (x <= x_high) & (y >= y_low) & (y <= y_high)]
    if len(y) < 2:
        return None
    return float(y.min()), float(y.max())


# --- scoring ------------------------------------------------------------------------------------

def _ground_truth(gt_dir: str | os.PathLike[str], test_list: str | os.PathLike[str]) -> list[tuple[str, GroundTruthFrame]]:
    """(frame id, the ground truth it is scored against) of every test-list line, paired as
    :func:`lanelab.metrics.openlane.evaluate_frames` pairs a prediction that carries the
    frame's own file_path (a file_path listed twice: the last frame of that file_path)."""
    relative_paths = read_test_list(test_list)
    frames = {rel: read_ground_truth(Path(gt_dir) / rel) for rel in dict.fromkeys(relative_paths)}
    by_file_path = {frames[rel].file_path: frames[rel] for rel in relative_paths}
    return [(rel, by_file_path[frames[rel].file_path]) for rel in relative_paths]


def score_blind_prior(
    prior: BlindPrior,
    gt_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig = OpenLaneConfig(),
) -> list[tuple[str, FrameResult]]:
    """(frame id, result) of the prior on every frame of a test list, scored against the
    ground truth in gt_dir with :func:`~lanelab.metrics.openlane.evaluate_frame`: the
    results :func:`~lanelab.metrics.openlane.evaluate_frames` gives on the prediction files
    of :func:`write_blind_prior_predictions`, without writing them."""
    return _scored(*prior.prediction_lanes(), _ground_truth(gt_dir, test_list), config)


def _scored(
    lanes: list[np.ndarray], categories: list[int], frames: Sequence[tuple[str, GroundTruthFrame]],
    config: OpenLaneConfig,
) -> list[tuple[str, FrameResult]]:  # fmt: skip
    """The prior's lanes and categories scored on every (frame id, ground truth) of frames."""
    return [(rel, evaluate_frame(gt.lanes, gt.visibility, gt.categories, lanes, categories, config)) for rel, gt in frames]


def write_blind_prior_predictions(
    prior: BlindPrior,
    gt_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
) -> Path:
    """The prior's prediction for every frame of a test list as OpenLane JSON files under
    out_dir, at the ground truth's relative paths (so any OpenLane evaluator scores them:
    ``evaluate(gt_dir, out_dir, test_list)``); out_dir."""
    out = Path(out_dir)
    for rel, gt in _ground_truth(gt_dir, test_list):
        write_json(path_inside(out, rel, f"{test_list}: line {rel!r}"), prior.prediction_json(gt.file_path))
    return out


# --- the report's reference ----------------------------------------------------------------------

def blind_prior_reference(
    stores: Sequence[str | os.PathLike[str]],
    gt_dir: str | os.PathLike[str],
    test_list: str | os.PathLike[str],
    config: OpenLaneConfig,
    scenarios: Sequence[Scenario] = (),
    split: str = "train",
    error_budget: bool = False,
) -> Reference:
    """The blind prior as a report's reference: computed from the first of ``stores`` whose
    ``split`` gives one (the others are the fallbacks, in order), scored on the test list's
    frames against gt_dir and grouped by the report's scenarios; with error_budget, its
    :func:`~lanelab.metrics.error_budget.error_budget` is in its details (``error_budget``).
    When no store gives one, the reference says why, store by store, and has no scores."""
    problems = []
    for store in dict.fromkeys(str(store) for store in stores):
        try:
            prior = compute_blind_prior(store, split, config)
        except BlindPriorError as err:
            problems.append(str(err))
            continue
        frames = _ground_truth(gt_dir, test_list)  # read once: scored, and the budget's
        lanes, categories = prior.prediction_lanes()
        results = _scored(lanes, categories, frames, config)
        details = prior_details(prior)
        if error_budget:
            predicted = [(gt, PredictionFrame(gt.file_path, lanes, categories)) for _, gt in frames]
            details[ERROR_BUDGET_KEY] = budget_of(predicted, config)
        return build_reference(NAME, describe(prior, problems), results, scenarios, details, layout_table(prior))
    why = "; ".join(problems) or "no clip store to compute it from"
    return build_reference(NAME, f"No blind prior could be computed: {why}.", None,
                           details={"unavailable": why})  # fmt: skip


def describe(prior: BlindPrior, problems: Sequence[str] = ()) -> str:
    """One paragraph: what the prior is and where it comes from."""
    text = (
        f"What a prediction that looks at no image scores: the mean lane layout of the {prior.split} "
        f"split of {prior.store} ({prior.num_labeled_frames} labeled frames), {len(prior.lanes)} straight, "
        "flat lanes, the same in every frame. A model below it has learnt less from the images "
        "than the labels' average layout already says."
    )
    if problems:
        text += " Not from " + "; ".join(problems) + "."
    return text


def prior_details(prior: BlindPrior) -> dict[str, Any]:
    """The prior as JSON-ready data (report.json's ``blind_prior``)."""
    return {
        "store": prior.store,
        "split": prior.split,
        "num_labeled_frames": prior.num_labeled_frames,
        "lanes": [{"slot": lane.slot, **asdict(lane)} for lane in prior.lanes],
    }


def layout_table(prior: BlindPrior) -> str:
    """The prior's lanes as a Markdown table, left to right."""
    lines = ["| Slot | x (m) | Category | y from (m) | y to (m) | Seen in (%) |", "|---|---:|---:|---:|---:|---:|"]
    for lane in prior.lanes:
        lines.append(f"| {lane.slot} | {lane.x:.2f} | {lane.category} | {lane.y_start:.1f} | {lane.y_end:.1f} "
                     f"| {100 * lane.presence:.1f} |")  # fmt: skip
    return "\n".join(lines) + "\n"
