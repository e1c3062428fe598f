"""SparseLaneSTP's extensions of the OpenLane metric: further error ranges and Vis-IoU.

Hand-computed cases; lanes in the ground frame (x right, y forward, z up).
"""

import math

import numpy as np
import pytest

from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frame, summarize

VIS_IOU = OpenLaneConfig(vis_iou=True)


def lane(*points):
    return np.array(points, dtype=float)


def test_official_config_has_the_two_official_ranges_and_no_vis_iou():
    config = OpenLaneConfig()
    assert config.error_ranges == [("close", slice(0, 38)), ("far", slice(38, 100))]
    assert config.pair_value_names == ["x_error_close", "x_error_far", "z_error_close",
                                       "z_error_far"]


def test_long_range_samples_every_metre_to_200_m_in_four_ranges():
    config = OpenLaneConfig.long_range()
    y = config.y_samples
    assert (y[0], y[-1], len(y)) == (3.0, 200.0, 198) and np.all(np.diff(y) == 1.0)
    # close 3..40 (38 samples), far 41..100 (60), 101..150 (50), 151..200 (50)
    assert config.error_ranges == [
        ("close", slice(0, 38)), ("far", slice(38, 98)),
        ("100_150", slice(98, 148)), ("150_200", slice(148, 198)),
    ]
    assert config.pair_value_names[-1] == "vis_iou"


def test_errors_per_range_are_means_over_the_samples_of_the_range():
    # dx = 0.001 y, dz = 0.002 y: the mean over a range is 0.001 (0.002) x its mean y.
    gt = lane([0.0, 1.0, 0.0], [0.0, 220.0, 0.0])
    pred = lane([0.001, 1.0, 0.002], [0.22, 220.0, 0.44])
    r = evaluate_frame([gt], [np.ones(2)], [1], [pred], [1], OpenLaneConfig.long_range())
    mean_y = {"close": 21.5, "far": 70.5, "100_150": 125.5, "150_200": 175.5}
    for name, y in mean_y.items():
        assert r.pair_values[f"x_error_{name}"][0] == pytest.approx(0.001 * y)
        assert r.pair_values[f"z_error_{name}"][0] == pytest.approx(0.002 * y)


def test_a_pair_seen_only_up_to_100_m_has_no_error_beyond():
    gt, pred = lane([0.0, 1.0, 0.0], [0.0, 99.0, 0.0]), lane([0.1, 1.0, 0.0], [0.1, 99.0, 0.0])
    r = evaluate_frame([gt], [np.ones(2)], [1], [pred], [1], OpenLaneConfig.long_range())
    assert r.pair_values["x_error_far"][0] == pytest.approx(0.1)
    assert math.isnan(r.pair_values["x_error_100_150"][0])
    summary = summarize([r])
    assert math.isnan(summary["x_error_150_200"]) and summary["f1"] == 1.0


# GT lane with an occluded stretch: points at y = 1, 40, 49, 61, 70, 110, visibility
# 1, 1, 0, 0, 1, 1. Officially (invisible points dropped) it covers 3..102 m: 100 samples.
# Its own visibility, interpolated, is above 0.5 before 44.5 m and after 65.5 m: it is seen
# at 3..44 (42 samples) and 66..102 (37 samples), 79 samples.
OCCLUDED_GT = lane(*[[0.0, y, 0.0] for y in (1, 40, 49, 61, 70, 110)])
OCCLUDED_VIS = np.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0])
GRID = np.arange(1.0, 111.0)  # predictions: one point a metre, 1 .. 110 m


def vis_iou(pred_points, pred_visibility=None):
    r = evaluate_frame(
        [OCCLUDED_GT], [OCCLUDED_VIS], [1], [pred_points], [1], VIS_IOU,
        pred_visibility=None if pred_visibility is None else [pred_visibility],
    )
    assert r.matched == [(0, 0)]
    return r.pair_values["vis_iou"][0]


def test_vis_iou_of_a_prediction_blind_to_the_occlusion():
    full = np.stack([np.zeros_like(GRID), GRID, np.zeros_like(GRID)], axis=1)
    assert vis_iou(full) == pytest.approx(79 / 100)  # no visibility: seen over its extent
    assert vis_iou(full, np.ones(len(GRID))) == pytest.approx(79 / 100)


def test_vis_iou_of_a_prediction_that_sees_the_occlusion():
    full = np.stack([np.zeros_like(GRID), GRID, np.zeros_like(GRID)], axis=1)
    occluded = np.where((GRID >= 45) & (GRID <= 65), 0.1, 0.9)
    assert vis_iou(full, occluded) == pytest.approx(1.0)


def test_vis_iou_of_a_prediction_that_ends_early():
    # Seen at 3..50 (48 samples): 42 shared with the GT's 79, union 48 + 37 = 85.
    short = lane([0.0, 1.0, 0.0], [0.0, 50.0, 0.0])
    assert vis_iou(short) == pytest.approx(42 / 85)


def test_vis_iou_is_averaged_over_matched_pairs():
    full = np.stack([np.zeros_like(GRID), GRID, np.zeros_like(GRID)], axis=1)
    short = lane([0.0, 1.0, 0.0], [0.0, 50.0, 0.0])
    frames = [
        evaluate_frame([OCCLUDED_GT], [OCCLUDED_VIS], [1], [p], [1], VIS_IOU) for p in (full, short)
    ]
    assert summarize(frames)["vis_iou"] == pytest.approx((79 / 100 + 42 / 85) / 2)
    assert "vis_iou" not in summarize([evaluate_frame([full], [np.ones(110)], [1], [full], [1])])


def test_invisible_predicted_points_count_as_absent_from_the_prediction():
    # Visibility below 0.5 from 60 m on: the same as a prediction that stops at 59 m.
    full = np.stack([np.full_like(GRID, 0.3), GRID, np.zeros_like(GRID)], axis=1)
    visibility = np.where(GRID < 60, 0.8, 0.2)
    gt = [lane([0.0, 1.0, 0.0], [0.0, 110.0, 0.0])]
    with_visibility = evaluate_frame(gt, [np.ones(2)], [1], [full], [1],
                                     pred_visibility=[visibility])
    cut = evaluate_frame(gt, [np.ones(2)], [1], [full[GRID < 60]], [1])
    assert summarize([with_visibility]) == summarize([cut])
    assert (with_visibility.recall_tp, with_visibility.precision_tp) == (0, 1)
