"""A trained checkpoint scored with lanelab-eval format=once: the model's lanes written as ONCE-3DLanes
prediction files (camera frame) for every frame of the split, and the ONCE report of them."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from once_helpers import SEQUENCES, adapt_tiny_once, write_tiny_once

from lanelab.evaluation.once_report import once_report
from lanelab.experiment.config import load_train_config
from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.experiment.train import train
from lanelab.lightning.once_writer import OnceWriter
from lanelab.lightning.predictions import PredictionBatch
from lanelab.metrics.once import evaluate_once
from lanelab.once.camera import lane_to_camera
from lanelab.once.file_paths import label_path
from lanelab.store import ClipStore

SPLIT = "val"  # ONCE's val folder, the store's val split (its one sequence, 3 labeled frames)
THRESHOLDS = [round(0.10 + 0.05 * i, 2) for i in range(18)]  # the official score thresholds


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("once")
    return adapt_tiny_once(write_tiny_once(root), root / "store")


@pytest.fixture(scope="module")
def checkpoint(store: Path, tmp_path_factory) -> Path:
    """last.ckpt of the tiny experiment after 2 steps on the store's train split (single-frame: its
    train and test sequences have no ego motion)."""
    out = tmp_path_factory.mktemp("trained")
    threads = torch.get_num_threads()  # the tiny experiment sets cpu_threads=1 for its process
    try:
        train(load_train_config([
            "experiment=tiny", f"data.store={store}", f"paths.output_dir={out}", "logger=none",
            "without_ego_motion=single_frame", "trainer.max_epochs=1", "trainer.limit_train_batches=2",
            "trainer.limit_val_batches=1",
        ]))  # fmt: skip
    finally:
        torch.set_num_threads(threads)
    return out / "checkpoints" / "last.ckpt"


@pytest.fixture(scope="module")
def evaluated(checkpoint: Path, store: Path, tmp_path_factory) -> tuple[Path, dict, list[PredictionBatch]]:
    """lanelab-eval format=once of the checkpoint on the val split: its output folder, report.json's
    content and the model's predictions as the writer received them."""
    out = tmp_path_factory.mktemp("eval") / "eval"
    received: list[PredictionBatch] = []
    write_on_batch_end = OnceWriter.write_on_batch_end

    def spy(self, trainer, pl_module, prediction, *args):
        received.append(prediction)
        write_on_batch_end(self, trainer, pl_module, prediction, *args)

    threads = torch.get_num_threads()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(OnceWriter, "write_on_batch_end", spy)
        try:
            report = evaluate_checkpoint(checkpoint, store, out, split=SPLIT, accelerator="cpu", num_pictures=0,
                                         picture_height=64, blind_prior=False, prior_store=None, format="once",
                                         without_ego_motion="single_frame")  # fmt: skip
        finally:
            torch.set_num_threads(threads)
    return out, report, received


def expected_files(out: Path) -> dict[str, Path]:
    """Relative label path -> the prediction file of every frame of the split, at the ONCE layout's path."""
    return {label_path(sequence, str(stamp)): out / "predictions" / sequence / "cam01" / f"{stamp}.json"
            for sequence, stamps in SEQUENCES[SPLIT].items() for stamp in stamps}  # fmt: skip


def test_every_frame_has_a_prediction_file_of_camera_frame_lanes(evaluated) -> None:
    out, _, _ = evaluated
    files = expected_files(out)
    assert sorted(p.relative_to(out / "predictions") for p in (out / "predictions").rglob("*.json")) == sorted(
        p.relative_to(out / "predictions") for p in files.values())
    for path in files.values():
        assert (out / "ground_truth" / path.relative_to(out / "predictions")).is_file()
        content = json.loads(path.read_text())
        assert list(content) == ["lanes"] and isinstance(content["lanes"], list)
        for lane in content["lanes"]:
            assert set(lane) == {"points", "score"}
            assert 0.0 <= lane["score"] <= 1.0
            points = np.array(lane["points"], np.float64)
            assert points.ndim == 2 and points.shape[0] >= 2 and points.shape[1] == 3
            assert np.isfinite(points).all() and (points[:, 2] > 0).all()  # in front of the camera


def test_the_points_written_are_the_models_lanes_in_the_camera_frame(evaluated, store: Path) -> None:
    out, _, received = evaluated
    clips = ClipStore(store)
    frames = lanes = 0
    for batch in received:
        dense = batch.predictions
        for i, clip_id in enumerate(batch.clip_ids):
            index = int(batch.frame_indices[i])
            (frame,) = clips.read_frames(clip_id, index, index + 1)
            stamp = frame.timestamp_ns // 1_000_000
            content = json.loads((out / "predictions" / clip_id / "cam01" / f"{stamp}.json").read_text())
            expected = []  # each proposal's points of visibility above the threshold, if 2 or more
            for n in dense.valid[i].nonzero()[:, 0].tolist():
                keep = (dense.visibility[i, n] > dense.threshold).numpy()
                if keep.sum() >= 2:
                    lane = dense.points[i, n].double().numpy()[keep]
                    expected.append((lane, lane_to_camera(lane, frame.T_lane_cam), float(dense.score[i, n])))
            assert len(content["lanes"]) == len(expected)
            for written, (lane, points, score) in zip(content["lanes"], expected):
                np.testing.assert_allclose(written["points"], points, rtol=0, atol=1e-9)
                # the axes by hand: camera z ~ lane y (forward), camera y ~ 1.5 m - lane z (down), x alike
                np.testing.assert_allclose(points[:, 2], lane[:, 1], rtol=1e-2)
                np.testing.assert_allclose(points[:, 1], 1.5 - lane[:, 2], atol=0.01 * np.abs(lane[:, 1]).max())
                np.testing.assert_allclose(points[:, 0], lane[:, 0], atol=1e-9)
                assert written["score"] == pytest.approx(score, abs=1e-12)
            frames += 1
            lanes += len(expected)
    assert frames == sum(len(stamps) for stamps in SEQUENCES[SPLIT].values())
    assert lanes > 0, "the tiny model proposed no lane: nothing was compared"


def test_the_report_has_every_threshold_and_the_best_row(evaluated) -> None:
    out, report, _ = evaluated
    assert report == json.loads((out / "report.json").read_text())
    assert report["metric"] == "ONCE-3DLanes"
    assert [row["score_threshold"] for row in report["thresholds"]] == pytest.approx(THRESHOLDS)
    frames = sum(len(stamps) for stamps in SEQUENCES[SPLIT].values())
    for row in report["thresholds"]:
        assert row["num_frames"] == frames and row["gt_lanes"] == 3 * frames
        assert 0 <= row["tp"] <= min(row["pred_lanes"], row["gt_lanes"])
    f1 = [row["f1"] for row in report["thresholds"] if row["f1"] is not None]  # None: no prediction above
    assert report["best"] == (max(report["thresholds"], key=lambda row: row["f1"]) if f1 else report["thresholds"][0])
    assert report["thresholds"] == once_report(evaluate_once(out / "ground_truth", out / "predictions"),
                                               report["inputs"])["thresholds"]  # fmt: skip
    scores = [lane["score"] for path in expected_files(out).values() for lane in json.loads(path.read_text())["lanes"]]
    assert [row["pred_lanes"] for row in report["thresholds"]] == [
        sum(score > threshold for score in scores) for threshold in THRESHOLDS]
    assert f"| **{report['best']['score_threshold']:.2f}** |" in (out / "report.md").read_text()


def test_another_split_into_the_same_folder_scores_that_split_alone(checkpoint: Path, store: Path, evaluated,
                                                                    tmp_path: Path) -> None:
    out = tmp_path / "eval"
    shutil.copytree(evaluated[0], out)  # the val split's files, from an earlier evaluation into the folder
    report = evaluate_checkpoint(checkpoint, store, out, split="test", accelerator="cpu", num_pictures=0,
                                 picture_height=64, blind_prior=False, prior_store=None, format="once",
                                 without_ego_motion="single_frame")  # fmt: skip
    frames = sum(len(stamps) for stamps in SEQUENCES["test"].values())
    assert report["best"]["num_frames"] == frames and report["best"]["gt_lanes"] == 3 * frames
    test_files = {label_path(sequence, str(stamp)) for sequence, stamps in SEQUENCES["test"].items() for stamp in stamps}
    for folder in ("predictions", "ground_truth"):
        assert {p.relative_to(out / folder).as_posix() for p in (out / folder).rglob("*.json")} == test_files
        assert [p.name for p in (out / folder).iterdir()] == list(SEQUENCES["test"])  # val's folders gone
