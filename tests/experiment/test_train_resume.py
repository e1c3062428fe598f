"""An interrupted run resumes from its last checkpoint and continues the step count."""

import csv
from pathlib import Path

import pytest
import torch
from tiny_store import tiny_overrides

from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train


def logged_steps(metrics_csv: Path) -> list[int]:
    with metrics_csv.open() as f:
        return [int(row["step"]) for row in csv.DictReader(f) if row.get("train/loss")]


@pytest.mark.slow
def test_resume_from_last_continues_the_step_count(tiny_store: Path, tmp_path: Path) -> None:
    # 6 training steps per epoch (2 streams over 12 frames): the first run stops mid-epoch, as if killed.
    common = ["logger=csv", "sampler=stream", "data.num_frames=1", "trainer.max_epochs=10", "trainer.limit_val_batches=1"]
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *common, "logger.csv.name=first", "trainer.max_steps=4")))
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert torch.load(last, weights_only=False)["global_step"] == 4

    overrides = [*common, "logger.csv.name=second", "trainer.max_steps=6", "ckpt_path=last"]
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *overrides)))
    assert logged_steps(tmp_path / "first" / "metrics.csv") == [0, 1, 2, 3]
    assert logged_steps(tmp_path / "second" / "metrics.csv") == [4, 5]
    assert torch.load(last, weights_only=False)["global_step"] == 6


def test_a_resumed_run_appends_to_its_history_from_the_final_step(tiny_store: Path, tmp_path: Path) -> None:
    # 6 steps per epoch: the first run validates at step 6 (a checkpoint) and stops at max_steps=8, mid-epoch.
    common = ["logger=csv", "sampler=stream", "data.num_frames=1", "trainer.max_epochs=10", "trainer.limit_val_batches=1"]
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *common, "trainer.max_steps=8")))
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert torch.load(last, weights_only=False)["global_step"] == 8  # not 6: the steps after it are kept

    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *common, "trainer.max_steps=10", "ckpt_path=last")))
    assert logged_steps(tmp_path / "csv" / "metrics.csv") == list(range(10))  # each step once, the first run's kept
    assert torch.load(last, weights_only=False)["global_step"] == 10
    assert not list((tmp_path / "checkpoints").glob("last-v*.ckpt"))


def test_a_run_resumed_after_a_crash_logs_each_step_once(tiny_store: Path, tmp_path: Path) -> None:
    # The first run checkpoints at step 6 (validation) and goes on to step 8; resuming from the step-6
    # checkpoint (as after a crash at step 8, before any later checkpoint) retrains steps 6 and 7.
    common = ["logger=csv", "sampler=stream", "data.num_frames=1", "trainer.max_epochs=10", "trainer.limit_val_batches=1"]
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *common, "trainer.max_steps=8")))
    (at_six,) = (tmp_path / "checkpoints").glob("epoch*step0000006.ckpt")
    history = tmp_path / "csv" / "metrics.csv"
    assert logged_steps(history) == list(range(8))

    before = history.read_text().splitlines()
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *common, "trainer.max_steps=10", f"ckpt_path={at_six}")))
    after = history.read_text().splitlines()
    assert after[:8] == before[:8]  # the header and the 7 rows logged before the step-6 checkpoint
    steps = logged_steps(history)
    assert steps == sorted(set(steps)) and steps[:6] == list(range(6))  # each step once: 6 and 7 from the resumed run
    assert len(steps) == 10
