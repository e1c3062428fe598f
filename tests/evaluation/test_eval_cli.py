"""lanelab-eval end to end: prints the tables, writes JSON, Markdown and pictures; malformed
inputs and bad options are named."""

import json
import subprocess
import sys

import cv2
import pytest
from eval_helpers import NAMES, write_prediction_set

from lanelab.experiment.eval_cli import run
from lanelab.evaluation.config import ConfigError, load_eval_config
from lanelab.json_files import LaneFileError
from lanelab.metrics import openlane


def options(data, out, *extra):
    return [f"gt={data.gt}", f"pred={data.pred}", f"test_list={data.test_list}", f"out={out}", *extra]


def run_eval(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lanelab.experiment.eval_cli", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_the_command_prints_the_tables_and_writes_the_report_and_pictures(tmp_path):
    data = write_prediction_set(tmp_path)
    out = tmp_path / "out"
    result = run_eval(*options(data, out, f"scenario_lists={data.scenario_lists}", "pictures.height=96"))
    assert result.returncode == 0, result.stderr
    assert "Overall" in result.stdout and "Cat. acc. (%)" in result.stdout
    assert "80.0  100.0   66.7  83.3" in result.stdout  # All, Curve, Night, Mean
    assert f"wrote {out / 'report.json'}, {out / 'report.md'}, {out / 'pictures.png'}" in result.stdout

    assert json.loads((out / "report.json").read_text())["overall"]["f1"] == pytest.approx(0.8)
    assert "| All | Curve | Night | Mean |" in (out / "report.md").read_text()
    picture = cv2.imread(str(out / "pictures.png"))
    # One row per frame (3 frames, 4 asked) over a legend strip: a row less is one row's height less.
    fewer = tmp_path / "fewer"
    assert run_eval(*options(data, fewer, "pictures.height=96", "pictures.num_frames=2")).returncode == 0
    row = picture.shape[0] - cv2.imread(str(fewer / "pictures.png")).shape[0]
    assert row >= 96 and 3 * row < picture.shape[0] < 4 * row


def test_long_range_and_no_pictures(tmp_path, capsys):
    data = write_prediction_set(tmp_path)
    written = run(load_eval_config(options(data, tmp_path / "out", "long_range=true", "pictures.num_frames=0")))
    assert [path.name for path in written] == ["report.json", "report.md"]
    assert "x err. 150-200 (m)" in capsys.readouterr().out
    assert json.loads(written[0].read_text())["metric"]["extra_ranges"] == [100.0, 150.0]


def test_the_error_budget_is_asked_for(tmp_path, capsys):
    data = write_prediction_set(tmp_path)
    plain = json.loads(run(load_eval_config(options(data, tmp_path / "plain", "pictures.num_frames=0")))[0].read_text())
    assert "error_budget" not in plain
    written = run(load_eval_config(options(data, tmp_path / "out", "error_budget=true", "pictures.num_frames=0")))
    budget = json.loads(written[0].read_text())["error_budget"]
    assert budget["as predicted"]["f1"] == pytest.approx(plain["overall"]["f1"])
    assert budget["missed lanes"]["f1"] >= budget["as predicted"]["f1"]
    assert "Where the F1 goes" in capsys.readouterr().out and "| far positions |" in written[1].read_text()


def test_the_error_budget_reads_each_file_once(tmp_path, monkeypatch):
    data = write_prediction_set(tmp_path)
    reads = []
    read_prediction = openlane.read_prediction
    monkeypatch.setattr(openlane, "read_prediction", lambda path: reads.append(path) or read_prediction(path))
    run(load_eval_config(options(data, tmp_path / "out", "error_budget=true", "pictures.num_frames=0")))
    assert len(reads) == len(set(reads)) == 3  # the metric and the budget score the same frames


@pytest.mark.slow
def test_a_malformed_prediction_is_named(tmp_path):
    data = write_prediction_set(tmp_path)
    bad = data.pred_file("b")
    bad.write_text(json.dumps({"file_path": NAMES["b"]}))
    result = run_eval(*options(data, tmp_path / "out"))
    assert result.returncode == 1
    assert f"lanelab-eval: {bad}: missing key 'lane_lines'" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
@pytest.mark.parametrize("value", [float("nan"), float("inf")], ids=["nan", "inf"])
def test_a_prediction_with_nan_or_inf_points_is_named(tmp_path, value):
    data = write_prediction_set(tmp_path)
    bad = data.pred_file("b")
    prediction = json.loads(bad.read_text())
    prediction["lane_lines"][0]["xyz"][2][0] = value  # Python's JSON writes NaN / Infinity
    bad.write_text(json.dumps(prediction))
    result = run_eval(*options(data, tmp_path / "out"))
    assert result.returncode == 1
    assert result.stderr.strip() == f"lanelab-eval: {bad}: lane_lines[0].xyz holds NaN or infinity"


def test_a_prediction_of_another_frame_is_named(tmp_path):
    data = write_prediction_set(tmp_path)
    bad = data.pred_file("c")
    content = json.loads(bad.read_text())
    content["file_path"] = "validation/segment-9/1.jpg"
    bad.write_text(json.dumps(content))
    with pytest.raises(LaneFileError, match=f"{bad}: file_path 'validation/segment-9/1.jpg' names no ground-truth"):
        run(load_eval_config(options(data, tmp_path / "out")))


def test_a_missing_prediction_and_an_empty_test_list_are_named(tmp_path):
    data = write_prediction_set(tmp_path)
    data.pred_file("a").unlink()
    with pytest.raises(LaneFileError, match=f"{data.pred_file('a')}: cannot read the file"):
        run(load_eval_config(options(data, tmp_path / "out")))
    data.test_list.write_text("\n")
    with pytest.raises(LaneFileError, match="names no frame"):
        run(load_eval_config(options(data, tmp_path / "out")))


@pytest.mark.parametrize("option, message", [
    ("pictures.height=10", "pictures.height"),
    ("scenario_lists=/no/such/folder", "scenario_lists"),
])
def test_bad_options_are_named(tmp_path, option, message):
    data = write_prediction_set(tmp_path)
    with pytest.raises(ConfigError, match=message):
        load_eval_config(options(data, tmp_path / "out", option))


@pytest.mark.slow
def test_the_command_names_unknown_and_missing_options(tmp_path):
    data = write_prediction_set(tmp_path)
    unknown = run_eval(*options(data, tmp_path / "out", "long_rnage=true"))
    assert unknown.returncode != 0 and "long_rnage" in unknown.stderr + unknown.stdout
    added = run_eval(*options(data, tmp_path / "out", "+long_rnage=true"))  # "+" adds past the struct flag
    assert added.returncode == 2 and added.stderr.strip() == "lanelab-eval: bad option: long_rnage: no such option (check its spelling in the tool's conf/*.yaml)"
    missing = run_eval(f"pred={data.pred}")
    assert missing.returncode == 2 and "gt: missing" in missing.stderr
    assert not (tmp_path / "out").exists()
