"""The blind prior: its layout from a small synthetic store, its scores (the same as the
OpenLane evaluator's on its prediction files) and its place in the report."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from eval_helpers import write_prediction_set

from lanelab.evaluation.blind_prior import (
    NAME,
    BlindPrior,
    BlindPriorError,
    PriorLane,
    blind_prior_reference,
    compute_blind_prior,
    score_blind_prior,
    write_blind_prior_predictions,
)
from lanelab.experiment.eval_cli import run
from lanelab.evaluation.config import load_eval_config
from lanelab.evaluation.report import build_report, to_json, to_markdown, to_text
from lanelab.lanes import Lane
from lanelab.metrics.openlane import OpenLaneConfig, evaluate, evaluate_frames, summarize
from lanelab.metrics.scenarios import scenarios_of
from lanelab.openlane.lists import read_scenario_lists
from lanelab.store import ClipEntry, Manifest, write_clip, write_manifest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))  # the data tests' store helpers
from synthetic_clips import frame_record  # noqa: E402


def lane(track_id: int, x: float, category: int = 1, y_end: float = 60.0, y_start: float = 0.0,
         visible: bool = True) -> Lane:  # fmt: skip
    """A straight lane at x, points every 2 m from y_start to y_end."""
    y = np.arange(y_start, y_end + 1.0, 2.0)
    points = np.stack([np.full_like(y, x), y, np.zeros_like(y)], axis=1).astype(np.float32)
    return Lane(points, np.full(len(y), float(visible), np.float32), category, track_id=track_id)


def labeled_lanes(i: int) -> list[Lane]:
    """The lanes of the i-th labeled training frame (i = 0..9); see test_the_prior_has_the_expected_slots."""
    lanes = [
        # L1: -1.5 / -2.0 by turns, category 2 in frames 0-6 and 1 after, occluded in frames 8 and 9
        lane(1, -1.5 if i % 2 == 0 else -2.0, 2 if i < 7 else 1, y_end=40.0 + 2 * i, visible=i < 8),
        lane(3, 1.75),  # R1, every frame
        lane(9, -3.5, y_start=40.0),  # a merge far ahead: not in the near window, not ranked
    ]
    if i >= 4:
        lanes.append(lane(2, -5.25, 8))  # L2 in 6 of 10 frames: kept (rank 2 also where L1 is occluded)
    if 4 <= i < 8:
        lanes.append(lane(5, -8.75))  # L3 in 4 of 10 frames: dropped
    if i >= 5:
        lanes.append(lane(4, 5.25, 21))  # R2 in 5 of 10 frames, exactly half: kept
    return lanes


def build_prior_store(root: Path) -> Path:
    """Two train clips of 10 frames, every other one labeled (10 labeled frames in all), and
    a val clip with a lane the prior must not see."""
    entries, labeled = [], 0
    for number, split in enumerate(("train", "train", "val")):
        frames = []
        for position in range(10):
            record = frame_record(number, position, labeled=position % 2 == 0)
            if record.labeled:
                lanes = labeled_lanes(labeled) if split == "train" else [lane(7, 3.0)]
                labeled += split == "train"
                record = dataclasses.replace(record, lanes=lanes)
            frames.append(record)
        clip_id = f"clip{number:02d}"
        write_clip(root, clip_id, frames)
        entries.append(ClipEntry(clip_id, "synthetic", split, len(frames), frames[0].timestamp_ns,
                                 frames[-1].timestamp_ns))  # fmt: skip
    write_manifest(root, Manifest(clips=entries))
    return root


@pytest.fixture(scope="module")
def prior_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_prior_store(tmp_path_factory.mktemp("prior_store"))


def test_the_prior_has_the_expected_slots(prior_store: Path) -> None:
    prior = compute_blind_prior(prior_store)
    assert prior.num_labeled_frames == 10 and prior.split == "train" and prior.store == str(prior_store)
    slots = {lane.slot: lane for lane in prior.lanes}
    assert [lane.slot for lane in prior.lanes] == ["L2", "L1", "R1", "R2"]  # left to right; L3 and the merge gone
    # L1: seen in frames 0-7 (occluded after, but still rank 1: L2 stays L2), mean of -1.5 and -2.0,
    # category 2 in 7 of the 8, visible y from 4 m (the first point inside 3-103 m) to the median end.
    assert slots["L1"] == PriorLane("left", 1, -1.75, 2, 4.0, 47.0, 0.8)
    assert slots["L2"] == PriorLane("left", 2, -5.25, 8, 4.0, 60.0, 0.6)
    assert slots["R1"] == PriorLane("right", 1, 1.75, 1, 4.0, 60.0, 1.0)
    assert slots["R2"] == PriorLane("right", 2, 5.25, 21, 4.0, 60.0, 0.5)
    assert compute_blind_prior(prior_store) == prior  # deterministic


def test_the_metric_ranges_clip_the_prior(prior_store: Path) -> None:
    narrow = compute_blind_prior(prior_store, config=OpenLaneConfig(y_range=(10.0, 50.0), x_range=(-4.0, 4.0)))
    # Only the points inside the metric's box count: the lanes beyond |x| = 4 m are never seen.
    assert [(lane.slot, lane.y_start, lane.y_end) for lane in narrow.lanes] == [("L1", 10.0, 47.0), ("R1", 10.0, 50.0)]


def test_stores_without_a_prior_are_named(tmp_path: Path, prior_store: Path) -> None:
    with pytest.raises(BlindPriorError, match=f"{tmp_path / 'none'}.*no clip store manifest"):
        compute_blind_prior(tmp_path / "none")
    with pytest.raises(BlindPriorError, match="no test clips"):
        compute_blind_prior(prior_store, "test")
    unlabeled = tmp_path / "unlabeled"
    write_clip(unlabeled, "c", [frame_record(0, 0, labeled=False)])
    write_manifest(unlabeled, Manifest(clips=[ClipEntry("c", "synthetic", "train", 1, 0, 0)]))
    with pytest.raises(BlindPriorError, match="no labeled frame in the train split"):
        compute_blind_prior(unlabeled)


def four_lanes() -> BlindPrior:
    """The hand-made layout of four straight lanes, 3.5 m apart."""
    lanes = [PriorLane("left" if x < 0 else "right", 1, x, 1, 3.0, 103.0, 1.0) for x in (-5.25, -1.75, 1.75, 5.25)]
    return BlindPrior(tuple(lanes), "hand-made", "train", 1)


def same(a: dict, b: dict) -> bool:
    """Dicts of numbers equal, NaN equal to NaN."""
    return a.keys() == b.keys() and all(
        a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k]) and math.isnan(b[k])) for k in a
    )


@pytest.mark.parametrize("config", [OpenLaneConfig(), OpenLaneConfig.long_range()], ids=["official", "long_range"])
def test_scores_equal_the_evaluator_on_the_prediction_files(config: OpenLaneConfig, prior_store: Path,
                                                            tmp_path: Path) -> None:  # fmt: skip
    data = write_prediction_set(tmp_path)  # GT lanes at x = -1.8, 0 and 1.8 m, 1 to 110 m
    for prior in (compute_blind_prior(prior_store, config=config), four_lanes()):
        pred = write_blind_prior_predictions(prior, data.gt, data.test_list, tmp_path / f"prior_{len(prior.lanes)}")
        direct = score_blind_prior(prior, data.gt, data.test_list, config)
        from_files = evaluate_frames(data.gt, pred, data.test_list, config)
        assert [name for name, _ in direct] == [name for name, _ in from_files]
        assert [r.counts for _, r in direct] == [r.counts for _, r in from_files]
        assert same(summarize(r for _, r in direct), evaluate(data.gt, pred, data.test_list, config))
    # The hand-made layout against GT at -1.8, 1.8 / 0 / -1.8, 1.8: lanes 0.05 m off match, 0 matches none.
    overall = summarize(r for _, r in score_blind_prior(four_lanes(), data.gt, data.test_list))
    assert (overall["gt_lanes"], overall["pred_lanes"], overall["recall_tp"]) == (5, 12, 4)


def test_the_report_shows_the_prior_beside_the_predictions(prior_store: Path, tmp_path: Path) -> None:
    data = write_prediction_set(tmp_path)
    config = OpenLaneConfig()
    results = evaluate_frames(data.gt, data.pred, data.test_list, config)
    scenarios = scenarios_of(read_scenario_lists(data.scenario_lists), [name for name, _ in results])
    reference = blind_prior_reference([tmp_path / "missing", prior_store], data.gt, data.test_list, config, scenarios)
    report = build_report(results, config, scenarios, {"pred": str(data.pred)}, name="model", reference=reference)

    prior = summarize(r for _, r in score_blind_prior(compute_blind_prior(prior_store), data.gt, data.test_list))
    assert same(reference.overall, prior)
    markdown = to_markdown(report)
    assert "| Predictions | Frames | F1 (%) | P (%) |" in markdown
    assert "| model | 3 | 80.0 | 80.0 | 80.0 | 75.0 | 0.025 |" in markdown
    assert f"| {NAME} | 3 | {100 * prior['f1']:.1f} | {100 * prior['precision']:.1f} |" in markdown
    assert "| Predictions | All | Curve | Night | Mean |" in markdown and "| model | 80.0 | 100.0 | 66.7 | 83.3 |" in markdown
    assert "## Blind prior" in markdown and "| L1 | -1.75 | 2 | 4.0 | 47.0 | 80.0 |" in markdown
    assert f"train split of {prior_store}" in markdown and f"Not from {tmp_path / 'missing'}" in markdown
    text = to_text(report)
    assert "blind prior" in text and "Slot" in text

    data_json = to_json(report)["blind_prior"]
    assert data_json["overall"]["f1"] == pytest.approx(prior["f1"]) and data_json["store"] == str(prior_store)
    assert [lane["slot"] for lane in data_json["lanes"]] == ["L2", "L1", "R1", "R2"]
    assert [row["scenario"] for row in data_json["scenarios"]] == ["Curve", "Night"]


def test_a_prior_that_cannot_be_computed_says_why(tmp_path: Path) -> None:
    data = write_prediction_set(tmp_path)
    results = evaluate_frames(data.gt, data.pred, data.test_list)
    reference = blind_prior_reference([tmp_path / "missing"], data.gt, data.test_list, OpenLaneConfig())
    report = build_report(results, OpenLaneConfig(), reference=reference)
    markdown = to_markdown(report)
    assert f"No blind prior could be computed: {tmp_path / 'missing'}" in markdown
    assert "| Frames | F1 (%) |" in markdown and "| Predictions |" not in markdown  # the model's table alone
    assert "overall" not in to_json(report)["blind_prior"] and "unavailable" in to_json(report)["blind_prior"]


def test_lanelab_eval_shows_the_prior_only_with_a_prior_store(prior_store: Path, tmp_path: Path, capsys) -> None:
    data = write_prediction_set(tmp_path)
    files = [f"gt={data.gt}", f"pred={data.pred}", f"test_list={data.test_list}", "pictures.num_frames=0"]
    run(load_eval_config([*files, f"out={tmp_path / 'plain'}"]))
    assert "blind_prior" not in json.loads((tmp_path / "plain" / "report.json").read_text())
    run(load_eval_config([*files, f"out={tmp_path / 'prior'}", f"prior_store={prior_store}"]))
    report = json.loads((tmp_path / "prior" / "report.json").read_text())
    assert report["blind_prior"]["store"] == str(prior_store) and report["blind_prior"]["overall"]["num_frames"] == 3
    assert "blind prior" in capsys.readouterr().out
    run(load_eval_config([*files, f"out={tmp_path / 'off'}", f"prior_store={prior_store}", "blind_prior=false"]))
    assert "blind_prior" not in json.loads((tmp_path / "off" / "report.json").read_text())


def test_the_error_budget_puts_the_prior_beside_the_predictions(prior_store: Path, tmp_path: Path, capsys) -> None:
    data = write_prediction_set(tmp_path)
    files = [f"gt={data.gt}", f"pred={data.pred}", f"test_list={data.test_list}", "pictures.num_frames=0"]
    run(load_eval_config([*files, f"out={tmp_path / 'out'}", f"prior_store={prior_store}", "error_budget=true"]))
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    prior_budget = report["blind_prior"]["error_budget"]
    assert prior_budget["as predicted"]["f1"] == pytest.approx(report["blind_prior"]["overall"]["f1"])
    assert prior_budget["false lanes"]["pred_lanes"] <= prior_budget["as predicted"]["pred_lanes"]
    markdown = (tmp_path / "out" / "report.md").read_text()
    assert "## Where the F1 goes, beside the blind prior" in markdown
    assert f"| predictions | {100 * report['overall']['f1']:.1f} |" in markdown
    assert f"| {NAME} | {100 * report['blind_prior']['overall']['f1']:.1f} |" in markdown
