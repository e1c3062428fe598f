"""lanelab-eval on a checkpoint and a clip store: the model is rebuilt from the run config
inside the checkpoint and scores as it did at the end of its training run."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tiny_store import tiny_overrides
from train_command import eval_command, read_only
from train_command import run as run_command

from lanelab.config_checks import ConfigError
from lanelab.experiment.eval_cli import run
from lanelab.evaluation.config import load_eval_config
from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train


@pytest.mark.slow
def test_a_checkpoint_scores_as_at_the_end_of_its_run(tiny_store: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    one_epoch = ["trainer.max_epochs=1", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1",
                 "evaluation.enabled=true", "evaluation.num_pictures=1"]  # fmt: skip
    train(load_train_config(tiny_overrides(tiny_store, run_dir, *one_epoch)))
    at_training = json.loads((run_dir / "eval" / "report.json").read_text())
    (checkpoint,) = (run_dir / "checkpoints").glob("epoch*.ckpt")  # the best one, which the run evaluated

    out = tmp_path / "eval"
    written = run(load_eval_config([f"checkpoint={checkpoint}", f"store={tiny_store}", f"out={out}",
                                    "accelerator=cpu", "pictures.height=96"]))  # fmt: skip
    report = json.loads((out / "report.json").read_text())
    assert report["overall"] == at_training["overall"]
    assert report["overall"]["num_frames"] > 0
    assert out / "pictures.png" in written and (out / "pictures.png").stat().st_size > 0
    assert sorted(p.name for p in (out / "predictions").rglob("*.json")) == sorted(
        p.name for p in (run_dir / "eval" / "predictions").rglob("*.json")
    )


@pytest.mark.slow
def test_a_checkpoint_without_a_run_config_is_named(tmp_path: Path, tiny_store: Path) -> None:
    foreign = tmp_path / "foreign.ckpt"
    torch.save({"state_dict": {}}, foreign)
    result = subprocess.run([sys.executable, "-m", "lanelab.experiment.eval_cli", f"checkpoint={foreign}",
                             f"store={tiny_store}", f"out={tmp_path / 'out'}"],
                            capture_output=True, text=True, timeout=120)  # fmt: skip
    assert result.returncode == 2 and f"checkpoint={foreign}: holds no lanelab run config" in result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("overrides, message", [
    (["checkpoint={ckpt}"], "store: missing"),
    (["checkpoint={ckpt}", "store={store}", "gt={store}"], "gt: not used with checkpoint"),
    (["checkpoint={ckpt}", "store={store}", "long_range=true"], "long_range: applies to prediction files"),
    (["checkpoint={store}/nothing.ckpt", "store={store}"], "checkpoint=.* is not an existing file"),
])  # fmt: skip
def test_bad_checkpoint_options_are_named(overrides: list[str], message: str, tiny_store: Path, tmp_path: Path) -> None:
    ckpt = tmp_path / "x.ckpt"
    ckpt.touch()
    with pytest.raises(ConfigError, match=message):
        load_eval_config([o.format(ckpt=ckpt, store=tiny_store) for o in overrides])


@pytest.mark.slow
def test_an_out_folder_that_cannot_be_written_is_one_line(trained_checkpoint: Path, tiny_store: Path,
                                                          tmp_path: Path) -> None:  # fmt: skip
    locked = tmp_path / "read_only"
    out = locked / "eval"
    result = run_command(read_only(locked, eval_command(f"checkpoint={trained_checkpoint}", f"store={tiny_store}",
                                                        f"out={out}")))  # fmt: skip
    assert result.returncode == 2, result.stderr  # old code: 1 and a traceback, after predicting
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith(f"lanelab-eval: bad option: out={out}: cannot write there (")
