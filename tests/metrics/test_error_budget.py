"""The error budget fixes exactly the kind of error it names, and scores with the metric."""

from __future__ import annotations

import numpy as np
import pytest

from lanelab.evaluation.report import ERROR_BUDGET_KEY, build_report, to_json, to_markdown
from lanelab.metrics.error_budget import FIXES, associate, budget_table, error_budget, gains_table
from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frame, sample_ground_truth, sample_predictions
from lanelab.openlane.read import GroundTruthFrame, PredictionFrame

Y = np.arange(0.0, 111.0, 1.0)


def lane(x: float | np.ndarray, y: np.ndarray = Y) -> np.ndarray:
    """A lane (N, 3) on flat ground: x constant or one value per y."""
    return np.stack([np.broadcast_to(x, y.shape), y, np.zeros_like(y)], 1)


def frame(gt_lanes: list[np.ndarray], pred_lanes: list[np.ndarray]) -> tuple[GroundTruthFrame, PredictionFrame]:
    gt = GroundTruthFrame("f.jpg", gt_lanes, [np.ones(len(g)) for g in gt_lanes], [1] * len(gt_lanes), np.eye(3), np.eye(4))
    return gt, PredictionFrame("f.jpg", pred_lanes, [1] * len(pred_lanes))


def counts(scores: dict) -> tuple[int, int, int]:
    return scores["recall_tp"], scores["precision_tp"], scores["pred_lanes"]


def test_each_fix_repairs_only_its_own_kind_of_error():
    bends_away = lane(np.where(Y > 40, 1.75 + 3.0, 1.75))  # right to 40 m, 3 m off beyond
    # The false lane slants: with parallel lanes the metric's own assignment ties (an official quirk).
    frames = [frame(
        [lane(-1.75), lane(1.75), lane(5.25)],  # the last one no prediction is about
        [lane(-1.75), bends_away, lane(-7.0 - 0.03 * Y)],  # correct, far positions wrong, a false lane
    )]  # fmt: skip
    budget = error_budget(frames)
    assert list(budget) == ["as predicted", *FIXES]
    # (GT lanes found, predictions right, predictions)
    assert counts(budget["as predicted"]) == (1, 1, 3)
    assert counts(budget["far positions"]) == (2, 2, 3)
    assert counts(budget["positions"]) == (2, 2, 3)
    assert counts(budget["near positions"]) == (1, 1, 3)  # its near range was right already
    assert counts(budget["extents"]) == (1, 1, 3)
    assert counts(budget["missed lanes"]) == (2, 2, 4)
    assert counts(budget["false lanes"]) == (1, 1, 2)
    assert budget["as predicted"]["associated"] == 2
    assert (budget["as predicted"]["false"], budget["as predicted"]["missed"]) == (1, 1)


def test_a_near_fix_carries_its_correction_on_and_a_far_fix_leaves_the_near_range():
    biased = lane(1.75 + 1.7)  # 1.7 m off everywhere: beyond the metric's 1.5 m, within the association's 2 m
    budget = error_budget([frame([lane(1.75)], [biased])])
    assert counts(budget["as predicted"]) == (0, 0, 1)
    assert counts(budget["near positions"]) == (1, 1, 1)  # the far range moves with the near correction
    assert counts(budget["far positions"]) == (0, 0, 1)  # 38 near samples still 1.7 m off: under 75 %


def test_far_positions_reach_to_the_long_range_metrics_last_sample():
    y = np.arange(0.0, 210.0)
    off_beyond_100 = lane(np.where(y > 100, 1.75 + 3.0, 1.75), y)
    budget = error_budget([frame([lane(1.75, y)], [off_beyond_100])], OpenLaneConfig.long_range())
    assert counts(budget["as predicted"]) == (0, 0, 1)  # half its samples are 3 m off
    assert counts(budget["far positions"]) == (1, 1, 1)


def test_the_extents_fix_ends_a_lane_where_its_ground_truth_ends():
    short_gt = lane(1.75, np.arange(0.0, 51.0))  # seen to 50 m, predicted to 110 m
    budget = error_budget([frame([short_gt], [lane(1.8)])])
    assert counts(budget["as predicted"]) == (1, 0, 1)  # covers the GT, but less than half of it is GT
    assert counts(budget["extents"]) == (1, 1, 1)
    assert counts(budget["near positions"]) == (1, 0, 1)


def test_extents_extend_a_short_prediction_along_its_own_line():
    slanted = lane(1.0 + 0.02 * Y[Y <= 30], Y[Y <= 30])  # predicted to 30 m only
    gt = lane(1.0 + 0.02 * Y)
    budget = error_budget([frame([gt], [slanted])])
    assert counts(budget["as predicted"]) == (0, 1, 1)
    assert counts(budget["extents"]) == (1, 1, 1)
    assert budget["extents"]["x_error_far"] == pytest.approx(0.0, abs=1e-9)  # the slope went on, not a constant


def test_frames_without_predictions_or_lanes():
    budget = error_budget([frame([lane(1.75)], []), frame([], [lane(-1.75)]), frame([], [])])
    assert counts(budget["as predicted"]) == (0, 0, 1)
    assert counts(budget["missed lanes"]) == (1, 1, 2)  # the first frame's lane added
    assert counts(budget["false lanes"]) == (0, 0, 0)  # the second frame's prediction removed
    assert budget["as predicted"]["missed"] == budget["as predicted"]["false"] == 1


def test_association_is_one_to_one_and_bounded():
    config = OpenLaneConfig()
    gt_frame, pred_frame = frame([lane(1.75)], [lane(1.9), lane(1.6), lane(4.5)])
    gt = sample_ground_truth(gt_frame.lanes, gt_frame.visibility, gt_frame.categories, config)
    pred = sample_predictions(pred_frame.lanes, pred_frame.categories, config)
    assert associate(gt, pred, config, max_distance=2.0) in ([(0, 0)], [(0, 1)])
    assert associate(gt, pred, config, max_distance=0.1) == []


def test_as_predicted_is_the_metric_itself():
    rng = np.random.default_rng(0)
    gts = [lane(x + 0.01 * rng.standard_normal(len(Y))) for x in (-5.25, -1.75, 1.75, 5.25)]
    preds = [lane(x + 0.3 * np.sin(Y / 9)) for x in (-5.0, -1.0, 1.75, 8.0)]
    gt_frame, pred_frame = frame(gts, preds)
    budget = error_budget([(gt_frame, pred_frame)])
    direct = evaluate_frame(gt_frame.lanes, gt_frame.visibility, gt_frame.categories, pred_frame.lanes, pred_frame.categories)
    assert counts(budget["as predicted"]) == (direct.recall_tp, direct.precision_tp, direct.pred_count)


def test_budgets_compare_as_gains_with_their_spread():
    one = error_budget([frame([lane(1.75), lane(5.25)], [lane(1.75)])])  # 66.7 %, a lane missed
    two = error_budget([frame([lane(1.75), lane(5.25)], [lane(1.75), lane(5.25)])])  # 100 %
    table = gains_table({"model": [one, two], "prior": [one]})
    assert table.splitlines()[0].startswith("| predictions | F1 (%) | near positions | far positions |")
    assert "| model | 83.3 ± 23.6 | +0.0 ± 0.0 |" in table  # seeds: mean ± sample std
    assert table.splitlines()[3].startswith("| prior | 66.7 | +0.0 |")
    assert "| +33.3 |" in table.splitlines()[3]  # the prior's missed lane


def test_the_report_shows_the_budget():
    budget = error_budget([frame([lane(1.75), lane(5.25)], [lane(1.75)])])
    direct = evaluate_frame([lane(1.75), lane(5.25)], [np.ones(len(Y))] * 2, [1, 1], [lane(1.75)], [1])
    report = build_report([("f", direct)], OpenLaneConfig(), error_budget=budget)
    markdown = to_markdown(report)
    assert "## Where the F1 goes" in markdown
    assert budget_table(budget) in markdown
    assert "| missed lanes | 100.0 | +33.3 |" in markdown
    assert to_json(report)[ERROR_BUDGET_KEY]["missed lanes"]["f1"] == pytest.approx(1.0)
    assert ERROR_BUDGET_KEY not in to_json(build_report([("f", direct)], OpenLaneConfig()))
