"""A second model is its detector, its loss and one config: the toy detector (toy_detector.py)
trains, validates and predicts through LaneDetectionModule with nothing else new. Its config
is the shared module config (conf/module/lane_detection.yaml: optimiser, schedule, metric,
pictures) plus its net and criterion, as a conf/model/<name>.yaml would hold them."""

from __future__ import annotations

import csv
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate
from lightning.pytorch.loggers import CSVLogger
from omegaconf import DictConfig, OmegaConf
from tiny_setup import CONF, TRAINER, build_store, data_module

from lanelab.experiment.targets import check_targets
from lanelab.lightning import LaneDetectionModule, PredictionBatch

TOY = {
    "net": {"_target_": "toy_detector.ToyDetector", "num_lines": 4, "num_points": 8, "y_range": [3.0, 60.0]},
    "criterion": {"_target_": "toy_detector.ToyLoss", "y_range": "${..net.y_range}"},
}
FAST = ["model.optimizer.lr=1e-2", "model.scheduler.warmup_steps=1", "model.pictures.num_frames=0"]


def toy_config(*overrides: str) -> DictConfig:
    """The model node: conf/module/lane_detection.yaml as Hydra composes it, with TOY."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        shared = compose(overrides=["+module@model=lane_detection", *overrides]).model
    OmegaConf.set_struct(shared, False)  # a model's yaml adds its own keys
    return OmegaConf.merge(shared, TOY)


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("store"), [6, 5])


def test_the_toy_config_fits_what_it_builds():
    config = toy_config()
    check_targets(config)  # the net is a LaneDetector, the criterion a LaneCriterion, every key known
    config.net.num_lines = "four"
    with pytest.raises(ValueError, match="net.num_lines='four'"):
        check_targets(config)
    not_a_detector = OmegaConf.merge(toy_config(), {"net": {"_target_": "torch.nn.Identity"}})
    with pytest.raises(ValueError, match="net=.*expected LaneDetector"):
        check_targets(not_a_detector)


def test_a_toy_detector_learns_through_the_lane_detection_module(store, tmp_path):
    pl.seed_everything(0)
    module = instantiate(toy_config(*FAST))
    assert isinstance(module, LaneDetectionModule)
    trainer = pl.Trainer(
        max_steps=30, num_sanity_val_steps=0, logger=CSVLogger(tmp_path), log_every_n_steps=1,
        enable_checkpointing=False, **TRAINER,
    )  # fmt: skip
    windows = data_module(store, "window", num_frames=2, batch_size=4)  # forward(batch)
    trainer.fit(module, windows)
    with open(Path(trainer.log_dir) / "metrics.csv") as file:
        rows = [row for row in csv.DictReader(file) if row.get("train/loss")]
    losses = [float(row["train/loss"]) for row in rows]
    assert len(losses) == 30 and sum(losses[-5:]) < 0.7 * sum(losses[:5])
    assert {"train/loss_x", "train/loss_vis", "train/loss_cls"} <= rows[0].keys()  # every term the loss returns

    streams = data_module(store, "stream", num_frames=1, batch_size=2)  # reset(mask) and step(frame)
    (scores,) = trainer.validate(module, streams, verbose=False)
    assert 0.0 <= scores["val/f1"] <= 1.0 and scores["val/num_frames"] == 11
    batches = trainer.predict(module, streams)
    assert all(isinstance(batch, PredictionBatch) for batch in batches)
    assert batches[0].predictions.points.shape == (len(batches[0].file_paths), 4, 20, 3)
    assert torch.isfinite(batches[0].predictions.points).all()
