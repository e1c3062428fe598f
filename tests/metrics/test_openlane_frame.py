"""Hand-computed cases of the OpenLane metric, one rule each.

Lanes are given in the evaluator's ground frame (x right, y forward, z up). The y samples are
3, 4, ..., 102 m (100 samples); "close" is 3..40 m (38 samples), "far" 41..102 m (62).
"""

import math

import numpy as np
import pytest

from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frame, summarize


def lane(*points):
    return np.array(points, dtype=float)


def straight(x, y0=1.0, y1=110.0, z=0.0):
    """A straight lane at constant x from y0 to y1 (covers all samples for the defaults)."""
    return lane([x, y0, z], [x, y1, z])


def frame(gt_lanes, pred_lanes, gt_cats=None, pred_cats=None, gt_vis=None):
    gt_cats = gt_cats or [1] * len(gt_lanes)
    pred_cats = pred_cats or [1] * len(pred_lanes)
    gt_vis = gt_vis or [np.ones(len(g)) for g in gt_lanes]
    return evaluate_frame(gt_lanes, gt_vis, gt_cats, pred_lanes, pred_cats)


def test_defaults_are_the_official_ones():
    config = OpenLaneConfig()
    assert config.y_samples[0] == 3 and config.y_samples[-1] == 102 and len(config.y_samples) == 100
    assert (config.x_range, config.dist_threshold, config.ratio_threshold) == ((-10, 10), 1.5, 0.75)


def test_perfect_offset_match_counts_every_sample():
    # dx = 0.5 m on all 100 samples: distance < 1.5 everywhere, cost int(50) = 50 < 150.
    r = frame([straight(1.0)], [straight(1.5, z=0.2)])
    assert (r.gt_count, r.pred_count, r.matched) == (1, 1, [(0, 0)])
    assert (r.recall_tp, r.precision_tp, r.category_correct) == (1, 1, 1)
    assert r.x_error_close[0] == pytest.approx(0.5) and r.x_error_far[0] == pytest.approx(0.5)
    assert r.z_error_close[0] == pytest.approx(0.2) and r.z_error_far[0] == pytest.approx(0.2)


def test_samples_only_one_lane_sees_cost_the_threshold_but_never_count():
    # Prediction covers y 1..50.5: samples 3..50 (48) seen by both at distance 0; the 52
    # samples only the GT sees cost 1.5 each -> cost 78 < 150, matched.
    r = frame([straight(2.0)], [straight(2.0, y1=50.5)])
    assert r.matched == [(0, 0)]
    # 48 of the GT's 100 visible samples are close: 0.48 < 0.75, no recall hit;
    # 48 of the prediction's 48: precision hit.
    assert (r.recall_tp, r.precision_tp) == (0, 1)
    assert r.x_error_close[0] == 0.0 and r.x_error_far[0] == 0.0  # both-visible samples only


def test_pair_matched_but_true_positive_for_neither_side():
    # dx = 1.0 on samples 3..52 (50), 1.8 on 53..102 (50): cost int(50 + 90) = 140 < 150,
    # so the pair is matched, but only 50 % of either lane's samples are within 1.5 m.
    pred = lane([1.0, 1.0, 0.0], [1.0, 52.0, 0.0], [1.8, 53.0, 0.0], [1.8, 110.0, 0.0])
    r = frame([straight(0.0)], [pred])
    assert r.matched == [(0, 0)]
    assert (r.recall_tp, r.precision_tp, r.category_correct) == (0, 0, 1)
    assert r.x_error_close[0] == pytest.approx(1.0)
    assert r.x_error_far[0] == pytest.approx((12 * 1.0 + 50 * 1.8) / 62)
    summary = summarize([r])
    assert (summary["recall"], summary["precision"], summary["f1"]) == (0.0, 0.0, 0.0)
    assert summary["category_accuracy"] == 1.0  # over matched pairs, TP or not


def test_cost_of_150_or_more_is_no_match():
    # dx = 1.6 on all samples: cost int(160) -> not accepted; both lanes still counted.
    r = frame([straight(0.0)], [straight(1.6)])
    assert (r.gt_count, r.pred_count, r.matched) == (1, 1, [])
    assert len(r.x_error_close) == 0


def test_left_curbside_prediction_is_right_for_a_right_curbside_gt_only():
    # GT 21 (right curbside) predicted as 20 counts as correct; GT 20 predicted as 21 does not.
    gts, preds = [straight(-5.0), straight(5.0)], [straight(-5.0), straight(5.0)]
    r = frame(gts, preds, gt_cats=[21, 20], pred_cats=[20, 21])
    assert r.matched == [(0, 0), (1, 1)]
    assert r.category_correct == 1
    assert summarize([r])["category_accuracy"] == 0.5


def test_empty_frames():
    nothing = frame([], [])
    assert (nothing.gt_count, nothing.pred_count, nothing.matched) == (0, 0, [])
    only_gt = frame([straight(0.0)], [])
    only_pred = frame([], [straight(0.0)])
    assert (only_gt.gt_count, only_gt.pred_count) == (1, 0)
    assert (only_pred.gt_count, only_pred.pred_count) == (0, 1)

    summary = summarize([nothing, only_gt, only_pred])
    assert summary["num_frames"] == 3
    assert (summary["gt_lanes"], summary["pred_lanes"], summary["matched"]) == (1, 1, 0)
    # 0 / 0 ratios are 0 (where the official epsilons act), errors without pairs are NaN.
    assert (summary["recall"], summary["precision"], summary["f1"]) == (0.0, 0.0, 0.0)
    assert summary["category_accuracy"] == 0.0
    assert math.isnan(summary["x_error_close"]) and math.isnan(summary["z_error_far"])
    assert summarize([])["f1"] == 0.0


def test_lanes_listed_far_to_near():
    # Points are sorted by y before resampling, so order does not matter ...
    r = frame([lane([0.0, 4.0, 0.0], [0.0, 100.0, 0.0])], [lane([0.0, 100.0, 0.0], [0.0, 4.0, 0.0])])
    assert r.matched == [(0, 0)] and (r.recall_tp, r.precision_tp) == (1, 1)
    # ... except for the range test, which reads the first point as the near end: a lane
    # listed from 110 m down to 1 m "starts" beyond the last sample (102 m) and is dropped.
    r = frame([straight(0.0)], [lane([0.0, 110.0, 0.0], [0.0, 1.0, 0.0])])
    assert (r.gt_count, r.pred_count) == (1, 0)


def test_lanes_outside_the_x_range():
    # Points are pruned strictly inside |x| < 10: lanes at 12 m or exactly 10 m vanish.
    r = frame([straight(12.0), straight(10.0), straight(9.99)], [straight(-10.0)])
    assert (r.gt_count, r.pred_count) == (1, 0)
    # A prediction leaving the range keeps its points inside it: samples 3..50 (48).
    pred = lane([5.0, 1.0, 0.0], [5.0, 50.0, 0.0], [15.0, 51.0, 0.0], [15.0, 110.0, 0.0])
    r = frame([straight(5.0)], [pred])
    assert r.matched == [(0, 0)] and (r.recall_tp, r.precision_tp) == (0, 1)


def test_gt_points_with_zero_visibility_are_removed():
    # The invisible far point goes: the GT then spans 1..50 m, 48 samples, like the prediction.
    gt = lane([0.0, 1.0, 0.0], [0.0, 50.0, 0.0], [0.0, 110.0, 0.0])
    r = frame([gt], [straight(0.0, y1=50.0)], gt_vis=[np.array([1.0, 1.0, 0.0])])
    assert (r.recall_tp, r.precision_tp) == (1, 1)


def test_lanes_with_fewer_than_two_visible_samples_are_not_counted():
    # 2.5..3.5 m covers the single sample y = 3: the lane is dropped, not a false positive.
    r = frame([straight(0.0)], [straight(0.0, y0=2.5, y1=3.5)])
    assert (r.gt_count, r.pred_count) == (1, 0)


def test_two_column_predictions_have_zero_height():
    r = frame([straight(0.0, z=0.3)], [np.array([[0.0, 1.0], [0.0, 110.0]])])
    assert r.z_error_close[0] == pytest.approx(0.3)


def test_errors_average_over_pairs_and_skip_pairs_without_samples_in_range():
    # Frame 1: a pair seen only beyond 40 m (no close error) with dx = 1.0.
    far_only = frame([straight(0.0, y0=60.0)], [straight(1.0, y0=60.0)])
    assert math.isnan(far_only.x_error_close[0]) and far_only.x_error_far[0] == 1.0
    # Frame 2: a pair with dx = 0.2 everywhere.
    near = frame([straight(0.0)], [straight(0.2)])
    summary = summarize([far_only, near])
    assert summary["x_error_close"] == pytest.approx(0.2)  # far_only has no close error
    assert summary["x_error_far"] == pytest.approx((1.0 + 0.2) / 2)


def test_frame_counts_add_up_before_dividing():
    a = frame([straight(0.0), straight(4.0)], [straight(0.0)])
    b = frame([straight(0.0)], [straight(0.0), straight(-4.0), straight(7.0)])
    summary = summarize([a, b])
    assert summary["recall"] == pytest.approx(2 / 3)
    assert summary["precision"] == pytest.approx(2 / 4)
    assert summary["f1"] == pytest.approx(2 * (2 / 3) * 0.5 / (2 / 3 + 0.5))


def test_matched_pairs_index_the_input_lanes():
    # The first GT and the first prediction are pruned (|x| >= 10); indices still refer to
    # the lists given to evaluate_frame.
    r = frame([straight(12.0), straight(3.0)], [straight(20.0), straight(-6.0), straight(3.2)])
    assert (r.gt_count, r.pred_count, r.matched) == (1, 2, [(1, 2)])
