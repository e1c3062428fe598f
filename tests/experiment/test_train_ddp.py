"""trainer=ddp_cpu: two gloo processes train, and their test metric equals one process's on the
same checkpoint and data (the metric sums its counts over ranks; samplers pad, never drop)."""

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hydra.utils import instantiate
from tiny_store import tiny_overrides

from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train

# Under pytest the popen launcher would re-run pytest in the second process: spawn instead.
DDP = ["trainer=ddp_cpu", "trainer.strategy.start_method=spawn"]
# A short fit (with its validation pictures, written by rank zero alone), then the test stage on
# the 12 training frames (more than the test split's 6).
COMMON = ["trainer.max_epochs=1", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1",
          "data.splits.test=train", "test=true"]  # fmt: skip
COUNTS = ("num_frames", "gt_lanes", "pred_lanes", "matched", "recall_tp", "precision_tp", "category_correct")


@pytest.mark.slow
def test_two_processes_match_one(tiny_store: Path, tmp_path: Path) -> None:
    ddp = train(load_train_config(tiny_overrides(tiny_store, tmp_path / "ddp", *DDP, *COMMON)))
    assert len(list((tmp_path / "ddp" / "pictures").glob("val_pictures_*.png"))) == 2
    (checkpoint,) = (tmp_path / "ddp" / "checkpoints").glob("epoch*.ckpt")
    overrides = [*COMMON, "train=false", f"ckpt_path={checkpoint}"]
    single = train(load_train_config(tiny_overrides(tiny_store, tmp_path / "single", *overrides)))

    assert ddp["test/num_frames"] == 12
    for name in COUNTS:
        assert ddp[f"test/{name}"] == single[f"test/{name}"], name
    for name in ("f1", "precision", "recall", "x_error_close", "z_error_close"):
        a, b = ddp[f"test/{name}"], single[f"test/{name}"]
        assert (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9), name



@pytest.mark.parametrize("overrides", [
    ["model=sparselanestp"], ["model=sparselanestp", "sampler=stream", "data.num_frames=1"],
    ["model=sparselanestp", "model.net.use_tca=false"], ["model=latr_baseline"],
    ["model=bi2lane"], ["model=bi2lane", "model.net.direction=forward", "model.net.aggregation=line"],
    ["model=bi2lane_baseline"],
], ids=" ".join)  # fmt: skip
def test_every_parameter_gets_a_gradient_on_a_first_step(tiny_store: Path, tmp_path: Path, overrides: list[str]) -> None:
    # What lets trainer/ddp*.yaml run DDP with find_unused_parameters=false: a parameter without
    # a gradient (an empty memory at a stream's start, a head the baseline skips) would stall it.
    cfg = load_train_config(tiny_overrides(tiny_store, tmp_path, *overrides))
    datamodule, module = instantiate(cfg.data), instantiate(cfg.model)
    datamodule.setup("fit")
    module.train()
    module.training_step(next(iter(datamodule.train_dataloader())), 0).backward()
    assert [name for name, p in module.named_parameters() if p.requires_grad and p.grad is None] == []


@pytest.mark.slow
def test_a_non_finite_loss_on_one_rank_stops_both(tiny_store: Path, tmp_path: Path) -> None:
    """lanelab-train with two processes (the popen launcher, as users run it): rank 1's loss turns
    NaN at its second step, rank 0's stays finite. Both stop (before, rank 0 waited forever in the
    gradient all-reduce), and the command ends with rank 1's error naming its batch."""
    overrides = ["trainer=ddp_cpu", *COMMON, "trainer.limit_train_batches=4",
                 "model.criterion._target_=nan_on_one_rank.NaNOnRankOne"]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run([sys.executable, "-m", "lanelab.experiment.train", *tiny_overrides(tiny_store, tmp_path, *overrides)],
                            capture_output=True, text=True, timeout=240, env=env)  # fmt: skip
    assert result.returncode != 0
    assert "step 1: the loss is not finite (total=nan) on the batch of frames" in result.stderr
