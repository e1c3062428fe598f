"""The ONCE-3DLanes metric: hand-computed cases and the JSON formats.

Lanes are in the camera frame (x right, y down, z forward). Score thresholds are 0.10,
0.15, ..., 0.95 (18); a prediction counts at thresholds strictly below its score.
"""

import json
import math

import numpy as np
import pytest

from lanelab.json_files import LaneFileError
from lanelab.metrics.once import (
    OnceConfig,
    best,
    evaluate_once,
    evaluate_once_frame,
    summarize_once,
)

Z = np.arange(3.0, 51.0)  # one point a metre, 3 .. 50 m ahead


def straight(x, y=1.5, z=Z):
    """A lane straight ahead at lateral offset x, height y below the camera."""
    return np.stack([np.full_like(z, x), np.full_like(z, y), z], axis=1)


def frame(gts, preds, scores=None):
    return evaluate_once_frame(gts, preds, scores or [0.9] * len(preds))


def test_thresholds_are_the_official_ones():
    thresholds = OnceConfig().score_thresholds
    assert len(thresholds) == 18
    assert thresholds[0] == pytest.approx(0.10) and thresholds[-1] == pytest.approx(0.95)


def test_a_close_prediction_is_a_true_positive_up_to_its_score():
    # 0.2 m to the side at every point: mean distance 0.2 < 0.3.
    r = frame([straight(1.8)], [straight(2.0)], [0.5])
    assert r.gt_count == 1
    assert r.pred_count.tolist() == [1] * 8 + [0] * 10  # 0.10 .. 0.45 < 0.5; 0.5 is not
    assert r.tp.tolist() == [1] * 8 + [0] * 10
    assert r.distance_sum[0] == pytest.approx(0.2)
    rows = summarize_once([r])
    assert (rows[0]["f1"], rows[0]["precision"], rows[0]["recall"]) == (1.0, 1.0, 1.0)
    assert rows[0]["cd"] == pytest.approx(0.2 / (1 + 1e-5))  # Quirk: + 1e-5 always
    assert math.isnan(rows[-1]["precision"]) and rows[-1]["recall"] == 0.0
    assert math.isnan(rows[-1]["f1"]) and rows[-1]["cd"] == 0.0


def test_a_matched_prediction_too_far_is_not_a_true_positive():
    # 0.4 m aside: the 30-pixel (1.5 m) wide top-view strokes overlap, the pair is matched,
    # but its mean distance is 0.4 >= 0.3.
    r = frame([straight(1.8)], [straight(2.2)])
    assert (r.tp[0], r.pred_count[0]) == (0, 1)
    row = summarize_once([r])[0]
    assert (row["f1"], row["precision"], row["recall"], row["cd"]) == (0.0, 0.0, 0.0, 0.0)


def test_height_counts_but_depth_does_not():
    # Quirk: distances are measured in the camera's x-y plane.
    assert frame([straight(1.8)], [straight(1.8, y=1.75)]).tp[0] == 1  # 0.25 m lower
    assert frame([straight(1.8)], [straight(1.8, y=1.85)]).tp[0] == 0  # 0.35 m lower
    shifted = straight(1.8, z=Z + 5.0)  # 5 m further ahead: same x-y line
    r = frame([straight(1.8)], [shifted])
    assert r.tp[0] == 1 and r.distance_sum[0] == 0.0


def test_lanes_seen_only_beyond_10_m_are_matched_in_list_order():
    # Quirk: the matching cost looks at z < 10 m only. Lanes from 15 m on draw nothing, all
    # costs are 1, and Munkres pairs GT i with prediction i: listing the same two perfect
    # predictions the other way round scores no true positive.
    far = np.arange(15.0, 51.0)
    gts = [straight(-1.8, z=far), straight(1.8, z=far)]
    assert frame(gts, [straight(-1.8, z=far), straight(1.8, z=far)]).tp[0] == 2
    assert frame(gts, [straight(1.8, z=far), straight(-1.8, z=far)]).tp[0] == 0


def test_lanes_listed_far_to_near_are_reversed():
    r = frame([straight(1.8)[::-1]], [straight(2.0)])
    assert r.tp[0] == 1 and r.distance_sum[0] == pytest.approx(0.2)


def test_counts_and_distances_add_up_over_frames():
    a = frame([straight(1.8), straight(-1.8)], [straight(2.0)])  # 1 TP of 2 GT
    b = frame([straight(5.0)], [straight(5.1), straight(-5.0)])  # 1 TP of 2 predictions
    row = summarize_once([a, b])[0]
    assert (row["gt_lanes"], row["pred_lanes"], row["tp"], row["num_frames"]) == (3, 3, 2, 2)
    assert row["precision"] == pytest.approx(2 / 3) and row["recall"] == pytest.approx(2 / 3)
    assert row["cd"] == pytest.approx((0.2 + 0.1) / (2 + 1e-5))


def test_best_is_the_row_of_highest_f1():
    r = frame([straight(1.8), straight(-1.8)], [straight(1.8), straight(9.0)], [0.9, 0.3])
    rows = summarize_once([r])
    assert rows[0]["f1"] == 0.5 and rows[5]["f1"] == pytest.approx(2 / 3)  # 0.10 vs 0.35
    assert best(rows) is rows[4]  # 0.30: the 0.3-score prediction is no longer counted


def write(path, obj):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj))
    return path


@pytest.fixture
def dataset(tmp_path):
    """One sequence, two frames, in the official layout <sequence>/cam01/<frame>.json."""
    gt_a = {"lanes": [straight(1.8).tolist(), [[0.0, 1.5, 3.0]]], "calibration": []}
    gt_b = {"lanes": [straight(-1.8).tolist()]}
    write(tmp_path / "gt/seq/cam01/a.json", gt_a)
    write(tmp_path / "gt/seq/cam01/b.json", gt_b)
    pred_a = write(tmp_path / "pred/seq/cam01/a.json",
                   {"lanes": [{"points": straight(2.0).tolist(), "score": 0.8}]})
    write(tmp_path / "pred/seq/cam01/b.json", {"lanes": []})
    return tmp_path, pred_a


def test_evaluate_once_reads_the_official_layout(dataset):
    root, _ = dataset
    row = evaluate_once(root / "gt", root / "pred")[0]
    # The one-point GT lane is left out, as officially: 2 GT lanes, 1 found.
    assert (row["gt_lanes"], row["pred_lanes"], row["tp"], row["num_frames"]) == (2, 1, 1, 2)
    assert row["recall"] == 0.5


@pytest.mark.parametrize(
    "content, problem",
    [
        ({}, "missing key 'lanes'"),
        ({"lanes": [{"score": 0.5}]}, "missing key 'points' in lanes[0]"),
        ({"lanes": [{"points": [[0, 1, 2], [0, 1, 3]]}]}, "missing key 'score' in lanes[0]"),
        ({"lanes": [{"points": [[0, 1], [0, 2]], "score": 1}]}, "lanes[0].points must have shape"),
        ({"lanes": [{"points": [[0, 1, 2]], "score": 1}]}, "needs at least 2 points"),
        ({"lanes": [{"points": [[0, 1, 2], [0, 1, 3]], "score": "hi"}]}, "score must be a number"),
    ],
)
def test_malformed_predictions_name_the_file_and_the_problem(dataset, content, problem):
    root, pred_a = dataset
    pred_a.write_text(json.dumps(content))
    with pytest.raises(LaneFileError) as error:
        evaluate_once(root / "gt", root / "pred")
    assert str(pred_a) in str(error.value) and problem in str(error.value)


def test_a_missing_prediction_file_is_an_error(dataset):
    root, pred_a = dataset
    pred_a.unlink()
    with pytest.raises(LaneFileError, match="no prediction for ground-truth file"):
        evaluate_once(root / "gt", root / "pred")
