"""W&B (offline) and CSV logging: metrics, the resolved config and the prediction pictures."""

from pathlib import Path

import pytest
import yaml
from tiny_store import tiny_overrides

from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train

SHORT = ["sampler=stream", "data.num_frames=1", "trainer.max_epochs=1", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1"]


@pytest.mark.slow
def test_wandb_offline(tiny_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WANDB_MODE", "offline")  # no network, no account
    monkeypatch.setenv("WANDB_SILENT", "true")
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, "logger=wandb", *SHORT)))
    (run,) = (tmp_path / "wandb").glob("offline-run-*")
    (records,) = run.glob("run-*.wandb")
    data = records.read_bytes()
    assert b"val/f1" in data and b"train/loss" in data  # metrics
    assert str(tiny_store).encode() in data  # the resolved config (data.store)
    assert list((run / "files" / "media" / "images" / "val").glob("pictures_*.png"))


def test_csv(tiny_store: Path, tmp_path: Path) -> None:
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, "logger=csv", *SHORT)))
    header = (tmp_path / "csv" / "metrics.csv").read_text().splitlines()[0].split(",")
    assert {"val/f1", "val/x_error_close", "train/loss"} <= set(header)
    hparams = yaml.safe_load((tmp_path / "csv" / "hparams.yaml").read_text())
    assert hparams["data"]["store"] == str(tiny_store)
    assert list((tmp_path / "csv" / "pictures").glob("val_pictures_*.png"))
