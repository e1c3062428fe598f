"""OpenLane -> store -> a trained checkpoint's evaluation -> OpenLane files again: the files
line up with the official tree (predictions at each frame's own file_path, so the official
annotations, test list and images pair with them), the exported ground truth is the source
annotations point by point, and the report has OpenLane's case columns."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from openlane_helpers import REVERSED_LANE, TinyOpenLane, VAL_SEGMENT, stamp

from lanelab.evaluation.config import load_eval_config
from lanelab.experiment.config import load_train_config
from lanelab.experiment.eval_cli import run
from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.experiment.train import train
from lanelab.metrics.openlane import evaluate
from lanelab.openlane.file_paths import file_path_of
from lanelab.openlane.read import read_ground_truth
from lanelab.openlane.write import write_prediction
from lanelab.store import ClipStore

VAL_FRAMES = [f"validation/{VAL_SEGMENT}/{stamp(i)}" for i in range(3)]


@pytest.fixture(scope="module")
def evaluated(tiny: TinyOpenLane, store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """lanelab-eval checkpoint=... store=... split=val of a tiny model trained two steps on the store."""
    root = tmp_path_factory.mktemp("round_trip")
    train(load_train_config([
        "experiment=tiny", f"data.store={store}", f"paths.output_dir={root / 'run'}", "logger=none",
        "trainer.max_steps=2", "trainer.limit_val_batches=1",
        "without_ego_motion=single_frame",  # a segment of the tiny set has no pose (clips_without_pose)
    ]))  # fmt: skip
    (checkpoint,) = (root / "run" / "checkpoints").glob("epoch*.ckpt")
    evaluate_checkpoint(checkpoint, store, root / "eval", split="val", accelerator="cpu", num_pictures=1,
                        picture_height=64, blind_prior=False, prior_store=None)  # fmt: skip
    return root / "eval"


def test_files_lie_at_the_frames_own_file_paths(evaluated: Path) -> None:
    for folder in ("predictions", "ground_truth"):
        files = sorted(p.relative_to(evaluated / folder).with_suffix("").as_posix()
                       for p in (evaluated / folder).rglob("*.json"))  # fmt: skip
        assert files == VAL_FRAMES, folder
    assert (evaluated / "test_list.txt").read_text().split() == [f"{frame}.jpg" for frame in VAL_FRAMES]
    prediction = json.loads((evaluated / "predictions" / f"{VAL_FRAMES[0]}.json").read_text())
    assert prediction["file_path"] == f"{VAL_FRAMES[0]}.jpg"


def test_the_exported_ground_truth_is_the_source_point_by_point(tiny: TinyOpenLane, evaluated: Path) -> None:
    for frame in VAL_FRAMES:
        source = read_ground_truth(tiny.annotations / f"{frame}.json")
        exported = read_ground_truth(evaluated / "ground_truth" / f"{frame}.json")
        assert exported.file_path == source.file_path
        assert exported.categories == source.categories
        np.testing.assert_array_equal(exported.K, source.K)
        np.testing.assert_allclose(exported.T_ground_cam, source.T_ground_cam, atol=1e-12)
        assert len(exported.lanes) == len(source.lanes) == 3
        for i, (ours, theirs) in enumerate(zip(exported.lanes, source.lanes)):
            assert ours.shape == theirs.shape  # every point, in the file's order (lane 2 far to near)
            np.testing.assert_allclose(ours, theirs, atol=1e-5)  # the store's float32 metres
            np.testing.assert_array_equal(exported.visibility[i], source.visibility[i])
        assert source.lanes[REVERSED_LANE][0, 1] > source.lanes[REVERSED_LANE][-1, 1]


def test_the_exported_ground_truth_scores_as_the_source(tiny: TinyOpenLane, store: Path, evaluated: Path,
                                                        tmp_path: Path) -> None:  # fmt: skip
    """The store's own lanes as predictions (a perfect detector) and the model's predictions
    score the same against the official annotations and against the exported files."""
    perfect = tmp_path / "perfect"
    for frame in ClipStore(store).read_frames(VAL_SEGMENT):
        write_prediction(perfect, file_path_of(frame), frame.lanes)
    test_list = evaluated / "test_list.txt"
    for predictions in (perfect, evaluated / "predictions"):
        official, exported = (evaluate(gt, predictions, test_list)
                              for gt in (tiny.annotations, evaluated / "ground_truth"))  # fmt: skip
        assert official == pytest.approx(exported, abs=1e-6, nan_ok=True)  # errors: the store's float32 metres
    assert evaluate(evaluated / "ground_truth", perfect, test_list)["f1"] == pytest.approx(1.0)


def test_lanelab_eval_pairs_the_predictions_with_the_official_tree(tiny: TinyOpenLane, evaluated: Path,
                                                                   tmp_path: Path) -> None:  # fmt: skip
    out = tmp_path / "official"
    written = run(load_eval_config([
        f"gt={tiny.annotations}", f"pred={evaluated / 'predictions'}", f"test_list={tiny.test_list}",
        f"scenario_lists={tiny.scenario_lists}", f"images={tiny.images}", f"out={out}", "pictures.height=64",
    ]))  # fmt: skip
    assert out / "pictures.png" in written
    assert json.loads((out / "report.json").read_text())["overall"]["num_frames"] == 3


def test_the_report_has_the_openlane_case_columns(evaluated: Path) -> None:
    report = json.loads((evaluated / "report.json").read_text())
    openlane = {(row["scenario"], row["num_frames"]) for row in report["scenarios"] if row["group"] == "OpenLane"}
    assert openlane == {("Curve", 1), ("Night", 2)}  # the tiny dataset's lists: 1000_curve.txt, 1000_night.txt
    markdown = (evaluated / "report.md").read_text()
    assert "## OpenLane scenarios: F1 (%)" in markdown and "| All | Curve | Night | Mean |" in markdown
