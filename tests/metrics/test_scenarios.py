"""Per-scenario tables from OpenLane's scenario lists and from clip-store tags."""

import math

import numpy as np
import pytest

from lanelab.metrics.openlane import evaluate_frame
from lanelab.metrics.scenarios import (
    list_scenarios,
    markdown_table,
    mean_f1,
    scenario_rows,
    tag_scenarios,
)
from lanelab.openlane.lists import read_test_list


def straight(x):
    return np.array([[x, 1.0, 0.0], [x, 110.0, 0.0]])


def result(gt_xs, pred_xs):
    return evaluate_frame([straight(x) for x in gt_xs], [np.ones(2)] * len(gt_xs),
                          [1] * len(gt_xs), [straight(x) for x in pred_xs], [1] * len(pred_xs))


# a: 1 of 1 found; b: 1 of 2 found; c: 1 found, 1 false positive.
RESULTS = {
    "validation/seg/a.json": result([0.0], [0.0]),
    "validation/seg/b.json": result([0.0, 4.0], [0.0]),
    "validation/seg/c.json": result([0.0], [0.0, -4.0]),
}


def test_openlane_lists_become_labelled_scenarios_scored_over_their_frames(tmp_path):
    (tmp_path / "night.txt").write_text("validation/seg/a.jpg\nvalidation/seg/b.jpg\n")
    (tmp_path / "curve.txt").write_text("validation/seg/c.jpg\n")
    lists = {name: read_test_list(tmp_path / f"{name}.txt") for name in ("night", "curve")}
    rows = scenario_rows(RESULTS, list_scenarios(lists))
    assert [(r["group"], r["scenario"], r["num_frames"]) for r in rows] == [
        ("OpenLane", "Night", 2), ("OpenLane", "Curve", 1)]
    night, curve = rows
    # Night: 2 TP of 3 GT lanes, 2 of 2 predictions.
    assert (night["recall"], night["precision"]) == (pytest.approx(2 / 3), 1.0)
    assert night["f1"] == pytest.approx(0.8)
    assert (curve["recall"], curve["precision"], curve["f1"]) == (1.0, 0.5, pytest.approx(2 / 3))
    assert mean_f1(rows) == pytest.approx((0.8 + 2 / 3) / 2)


def test_frames_without_results_are_not_scored():
    rows = scenario_rows(RESULTS, list_scenarios({"up_down": ["validation/seg/a.json", "x"],
                                                  "merge_split": []}))
    assert [(r["scenario"], r["num_frames"], r["f1"]) for r in rows] == [
        ("Up & Down", 1, 1.0), ("Merge & Split", 0, 0.0)]


def test_tags_group_frames_by_value_as_table_7():
    tags = {
        "validation/seg/a.json": {"environment": "urban", "daytime": "night", "weather": "rain"},
        "validation/seg/b.json": {"environment": "highway", "daytime": "day", "weather": "rain"},
        "validation/seg/c.json": {"environment": "urban", "slope": "flat"},
    }
    scenarios = tag_scenarios(tags)
    assert [(s.group, s.name, len(s.frames)) for s in scenarios] == [
        ("Environment", "highway", 1), ("Environment", "urban", 2),
        ("Daytime / Weather", "day", 1), ("Daytime / Weather", "night", 1),
        ("Daytime / Weather", "rain", 2),
    ]
    by_slope = tag_scenarios(tags, {"slope": "Slope"})
    assert [(s.name, sorted(s.frames)) for s in by_slope] == [("flat", ["validation/seg/c.json"])]
    urban = scenario_rows(RESULTS, scenarios)[1]
    assert (urban["scenario"], urban["recall"], urban["precision"]) == ("urban", 1.0, 2 / 3)


def test_markdown_table_shows_percent_and_metres():
    rows = scenario_rows(RESULTS, list_scenarios({"night": ["validation/seg/b.json"]}))
    table = markdown_table(rows, ["scenario", "num_frames", "f1", "x_error_close",
                                  "x_error_100_150"])
    lines = table.splitlines()
    assert lines[0] == "| Scenario | Frames | F1 (%) | x err. close (m) | x err. 100-150 (m) |"
    assert lines[1] == "|---|---:|---:|---:|---:|"
    assert lines[2] == "| Night | 1 | 66.7 | 0.000 | – |"


def test_markdown_table_shows_missing_errors_as_a_dash():
    rows = scenario_rows(RESULTS, list_scenarios({"curve": []}))
    assert math.isnan(rows[0]["x_error_far"])
    assert markdown_table(rows, ["x_error_far"]).splitlines()[2] == "| – |"
