"""Bi²Lane and its single-frame baseline through the shared LaneDetectionModule, as the tiny preset
(experiment=tiny) builds them from conf/: the loss falls within a few steps, and a trained model
validates streaming (its frame cache) and windowed alike and predicts lanes."""

from __future__ import annotations

import csv
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from hydra.utils import instantiate
from lightning.pytorch.loggers import CSVLogger
from tiny_setup import TRAINER, build_store, data_module

from lanelab.experiment.config import load_train_config
from lanelab.experiment.targets import check_targets
from lanelab.lightning import LaneDetectionModule, PredictionBatch

FAST = ["model.optimizer.lr=2e-3", "model.scheduler.warmup_steps=1", "model.pictures.num_frames=0"]


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("store"), [6, 5])


def tiny_module(name: str, *overrides: str) -> LaneDetectionModule:
    cfg = load_train_config(["experiment=tiny", f"model={name}", "paths.output_dir=unused", *FAST, *overrides])
    check_targets(cfg.model)
    torch.manual_seed(0)
    return instantiate(cfg.model)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bi2lane", "bi2lane_baseline"])
def test_the_tiny_bi2lane_learns_through_the_lane_detection_module(store, tmp_path, name):
    pl.seed_everything(0)
    module = tiny_module(name)
    trainer = pl.Trainer(
        max_steps=25, num_sanity_val_steps=0, logger=CSVLogger(tmp_path), log_every_n_steps=1,
        enable_checkpointing=False, limit_val_batches=0, **TRAINER,
    )  # fmt: skip
    trainer.fit(module, data_module(store, "window", num_frames=4, batch_size=4))
    with open(Path(trainer.log_dir) / "metrics.csv") as file:
        rows = [row for row in csv.DictReader(file) if row.get("train/loss")]
    losses = [float(row["train/loss"]) for row in rows]
    assert len(losses) == 25 and sum(losses[-5:]) < 0.6 * sum(losses[:5])
    terms = {"train/loss_cls", "train/loss_reg", "train/loss_vis", "train/loss_seg"}
    assert terms | ({"train/loss_refine"} if name == "bi2lane" else set()) <= rows[0].keys()

    streams = data_module(store, "stream", num_frames=1, batch_size=2)  # step(frame) with the frame cache
    windows = data_module(store, "window", num_frames=4, batch_size=2)  # forward(batch), padded clip starts
    evaluator = pl.Trainer(logger=False, **TRAINER)
    (streamed,) = evaluator.validate(module, streams, verbose=False)
    (windowed,) = evaluator.validate(module, windows, verbose=False)
    assert streamed["val/num_frames"] == windowed["val/num_frames"] == 11
    assert streamed["val/f1"] == pytest.approx(windowed["val/f1"], abs=1e-6)
    batches = evaluator.predict(module, streams)
    assert all(isinstance(batch, PredictionBatch) for batch in batches)
    assert torch.isfinite(batches[0].predictions.points).all()
