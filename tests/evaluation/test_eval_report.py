"""The report's tables and files, on a prediction set with hand-computed scores."""

import json

import pytest
from eval_helpers import NAMES, write_prediction_set

from lanelab.evaluation.report import build_report, to_json, to_markdown, to_text, write_report
from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frames
from lanelab.metrics.scenarios import scenarios_of
from lanelab.openlane.lists import read_scenario_lists


def report_of(tmp_path, config=OpenLaneConfig(), with_scenarios=True):
    data = write_prediction_set(tmp_path)
    results = evaluate_frames(data.gt, data.pred, data.test_list, config)
    scenarios = scenarios_of(read_scenario_lists(data.scenario_lists), [name for name, _ in results]) \
        if with_scenarios else []
    return build_report(results, config, scenarios, {"pred": str(data.pred)})


def test_overall_numbers_are_the_hand_computed_ones(tmp_path):
    overall = report_of(tmp_path).overall
    assert overall["f1"] == pytest.approx(0.8) and overall["recall"] == overall["precision"] == 0.8
    assert overall["category_accuracy"] == 0.75
    assert overall["x_error_close"] == pytest.approx(0.025) and overall["x_error_far"] == pytest.approx(0.025)
    assert overall["z_error_close"] == 0.0


def test_markdown_has_the_papers_tables(tmp_path):
    markdown = to_markdown(report_of(tmp_path))
    assert "- frames: 3" in markdown and f"- pred: {tmp_path / 'pred'}" in markdown
    assert ("| Frames | F1 (%) | P (%) | R (%) | Cat. acc. (%) | x err. close (m) | x err. far (m) "
            "| z err. close (m) | z err. far (m) |") in markdown
    assert "| 3 | 80.0 | 80.0 | 80.0 | 75.0 | 0.025 | 0.025 | 0.000 | 0.000 |" in markdown
    # Table 4 / Table II shape: All, each scenario, the mean over scenarios
    assert "## OpenLane scenarios: F1 (%)" in markdown
    assert "| All | Curve | Night | Mean |\n|---:|---:|---:|---:|\n| 80.0 | 100.0 | 66.7 | 83.3 |" in markdown
    assert "| OpenLane | Night | 2 | 66.7 | 66.7 | 66.7 | 50.0 |" in markdown


def test_text_aligns_the_columns(tmp_path):
    text = to_text(report_of(tmp_path, with_scenarios=False))
    lines = text.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("Frames"))
    title, values = lines[header], lines[header + 1]
    assert len(title) == len(values)  # right-aligned columns end together
    assert title.index("F1 (%)") + len("F1 (%)") == values.index("80.0") + len("80.0")
    assert "scenarios" not in text


def test_long_range_columns_are_named_by_their_ranges(tmp_path):
    report = report_of(tmp_path, OpenLaneConfig.long_range())
    markdown = to_markdown(report)
    for label in ("x err. 0-40 (m)", "x err. 40-100 (m)", "x err. 100-150 (m)", "z err. 150-200 (m)", "Vis-IoU (%)"):
        assert label in markdown
    assert "errors to 200 m and Vis-IoU" in markdown
    # lanes end at 110 m: nothing to measure beyond 150 m
    assert to_json(report)["overall"]["x_error_150_200"] is None


def test_json_is_strict_and_complete(tmp_path):
    report = report_of(tmp_path / "data")
    paths = write_report(report, tmp_path / "out")
    assert [p.name for p in paths] == ["report.json", "report.md"]
    data = json.loads(paths[0].read_text(), parse_constant=lambda name: pytest.fail(f"{name} in JSON"))
    assert data["overall"]["f1"] == pytest.approx(0.8) and data["metric"]["y_range"] == [3.0, 103.0]
    assert [row["scenario"] for row in data["scenarios"]] == ["Curve", "Night"]
    assert data["mean_scenario_f1"]["OpenLane"] == pytest.approx((1 + 2 / 3) / 2)
    assert paths[1].read_text() == to_markdown(report)


def test_a_scenario_without_frames_shows_dashes(tmp_path):
    data = write_prediction_set(tmp_path)
    (data.scenario_lists / "up_down.txt").write_text("validation/segment-9/1.jpg\n")
    results = evaluate_frames(data.gt, data.pred, data.test_list)
    report = build_report(results, OpenLaneConfig(), scenarios_of(read_scenario_lists(data.scenario_lists), NAMES.values()))
    assert "| All | Up & Down | Curve | Night | Mean |" in to_markdown(report)
    assert "| OpenLane | Up & Down | 0 | 0.0 | 0.0 | 0.0 | 0.0 | – |" in to_markdown(report)
    assert to_json(report)["scenarios"][0]["x_error_close"] is None
