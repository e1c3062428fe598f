"""A tiny SparseLaneSTP overfits one synthetic clip; its OpenLane files score as the in-loop
metric does (to resampling); validation draws pictures. One training run serves the three tests."""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import lightning.pytorch as pl
import numpy as np
import pytest
from hydra.utils import instantiate
from lightning.pytorch.loggers import CSVLogger
from tiny_setup import TRAINER, build_store, data_module, model_config

from lanelab.lightning import OpenLaneWriter
from lanelab.metrics import evaluate
from lanelab.viz import GT_COLOR, PREDICTION_COLOR
from lanelab.viz.panels import strip_height

pytestmark = pytest.mark.slow  # the three tests read one 300-step training run

STEPS = 300  # windowed training, 4 windows of 2 frames a step: 150 passes over the clip
FAST = ["model.optimizer.lr=2e-3", "model.scheduler.warmup_steps=20", "model.scheduler.min_lr=1e-4"]  # a high lr for a short run


@dataclass
class Run:
    scores: dict[str, float]  # the in-loop metric after training (val/...)
    log_dir: Path
    files: Path  # OpenLaneWriter output of the same frames
    picture_height: int  # model.pictures.height


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    root = tmp_path_factory.mktemp("overfit")
    store = build_store(root / "store", [8])
    pl.seed_everything(0)
    module = instantiate(model_config("sparselanestp", *FAST))
    data = data_module(store, "window", num_frames=2, batch_size=4)
    trainer = pl.Trainer(
        max_steps=STEPS, check_val_every_n_epoch=STEPS, num_sanity_val_steps=0, gradient_clip_val=20.0,
        logger=CSVLogger(root / "logs"), log_every_n_steps=1, enable_checkpointing=False, **TRAINER,
    )  # fmt: skip
    start = time.perf_counter()
    trainer.fit(module, data)  # on one core (conftest.py)
    seconds = time.perf_counter() - start
    (scores,) = trainer.validate(module, data, verbose=False)
    print(f"\noverfit: {STEPS} steps in {seconds:.1f} s, F1 {scores['val/f1']:.3f}")

    writer = OpenLaneWriter(root / "files", ground_truth=store)
    pl.Trainer(logger=False, callbacks=[writer], **TRAINER).predict(module, data, return_predictions=False)
    return Run(scores, Path(trainer.log_dir), root / "files", module.pictures["height"])


def test_a_tiny_model_overfits_one_clip(run):
    assert run.scores["val/f1"] >= 0.95
    assert run.scores["val/num_frames"] == 8
    with open(run.log_dir / "metrics.csv") as file:
        losses = [float(row["train/loss"]) for row in csv.DictReader(file) if row.get("train/loss")]
    assert len(losses) == STEPS and max(losses[-10:]) < 0.05 * min(losses[:10])


def test_openlane_files_score_as_the_in_loop_metric(run):
    """The files hold the store's lanes, the in-loop metric sees them resampled at data.y_grid
    (the training targets): the same matches, errors a fraction of a millimetre apart."""
    files = evaluate(run.files / "ground_truth", run.files / "predictions", run.files / "test_list.txt")
    assert files["num_frames"] == 8
    for key, value in files.items():
        tolerance = 1e-3 if "_error_" in key else 1e-6  # metres, else counts and fractions
        assert run.scores[f"val/{key}"] == pytest.approx(value, rel=1e-6, abs=tolerance), key


def test_validation_logs_pictures(run):
    pictures = sorted((run.log_dir / "pictures").glob("val_pictures_step*.png"))
    assert len(pictures) == 2  # model.pictures.num_frames in the tests
    picture = cv2.imread(str(pictures[0]))
    assert picture.shape[0] > run.picture_height + 2 * strip_height(run.picture_height)  # with title and legend
    assert all(np.all(picture == color, axis=-1).any() for color in (GT_COLOR, PREDICTION_COLOR))  # a trained model
