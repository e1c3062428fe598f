"""No checkpoint of NaN or inf weights is ever written: LaneCheckpoint refuses (a warning names
the file and the step), also at the end of training, and the module refuses any other save."""

from __future__ import annotations

import math
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from hydra.utils import instantiate
from tiny_setup import TRAINER, build_store, data_module, model_config

from lanelab.finite import NonFiniteError
from lanelab.lightning.checkpoint import LaneCheckpoint


class SpoilWeights(pl.Callback):
    """Sets one weight to NaN after the optimiser step of step `step` (as a NaN gradient would)."""

    def __init__(self, step: int) -> None:
        self.step = step

    def on_train_batch_end(self, trainer: pl.Trainer, module: pl.LightningModule, *args) -> None:
        if trainer.global_step == self.step:
            with torch.no_grad():
                next(module.net.parameters()).view(-1)[0] = math.nan


def test_nan_weights_are_never_saved(tmp_path: Path) -> None:
    torch.manual_seed(0)
    module = instantiate(model_config("sparselanestp"))
    dm = data_module(build_store(tmp_path / "store", [4, 4]), "stream", num_frames=1, batch_size=2)
    checkpoint = LaneCheckpoint(dirpath=tmp_path / "ckpt", save_last=True, save_on_exception=True,
                                every_n_train_steps=1, enable_version_counter=False)  # fmt: skip
    # The last step's weights turn NaN: neither its checkpoint nor the last one at the end of training is written.
    trainer = pl.Trainer(max_steps=2, callbacks=[SpoilWeights(2), checkpoint], logger=False, **TRAINER)
    with pytest.warns(UserWarning) as warnings:
        trainer.fit(module, dm)
    refusals = [str(w.message) for w in warnings if str(w.message).startswith("not saving")]
    # the step, the epoch's end (which max_steps cuts short), then the end of training
    assert [Path(r.split()[2]).name for r in refusals] == ["epoch=0-step=2.ckpt", "last.ckpt", "last.ckpt", "last.ckpt"]
    assert all(" at step 2: NaN or inf weights in 1 tensors (net." in r for r in refusals)
    last = torch.load(tmp_path / "ckpt" / "last.ckpt", weights_only=False)
    assert last["global_step"] == 1  # the last finite weights
    assert all(torch.isfinite(v).all() for v in last["state_dict"].values() if v.is_floating_point())
    with pytest.raises(NonFiniteError, match="not saving a checkpoint of NaN or inf weights in 1 tensors"):
        trainer.save_checkpoint(tmp_path / "by_hand.ckpt")
    assert not (tmp_path / "by_hand.ckpt").exists()


class WorseEachValidation(pl.Callback):
    """Logs a score that is best at the first validation and worse at each after it."""

    def on_validation_epoch_end(self, trainer: pl.Trainer, module: pl.LightningModule) -> None:
        module.log("probe", float(trainer.current_epoch))


class LastCheckpointSteps(pl.Callback):
    """The step last.ckpt holds at the start of each epoch (after the previous epoch's validation)."""

    def __init__(self, path: Path) -> None:
        self.path, self.steps = path, []

    def on_train_epoch_start(self, trainer: pl.Trainer, module: pl.LightningModule) -> None:
        if trainer.current_epoch > 0:
            self.steps.append(torch.load(self.path, weights_only=False)["global_step"])


def test_last_is_saved_after_every_validation_not_only_with_a_new_best(tmp_path: Path) -> None:
    # Issue 37 case 7: Lightning wrote last.ckpt only with a new best, so it stayed at the first epoch's step.
    torch.manual_seed(0)
    module = instantiate(model_config("sparselanestp"))
    dm = data_module(build_store(tmp_path / "store", [4, 4]), "stream", num_frames=1, batch_size=2)
    checkpoint = LaneCheckpoint(dirpath=tmp_path / "ckpt", monitor="probe", mode="min", save_top_k=1, save_last=True,
                                enable_version_counter=False)  # fmt: skip
    probe = LastCheckpointSteps(tmp_path / "ckpt" / "last.ckpt")
    trainer = pl.Trainer(max_epochs=3, limit_train_batches=2, limit_val_batches=1, logger=False, default_root_dir=tmp_path,
                         callbacks=[WorseEachValidation(), probe, checkpoint], **TRAINER)  # fmt: skip
    trainer.fit(module, dm)
    assert probe.steps == [2, 4]  # old code: [2, 2]
    assert torch.load(tmp_path / "ckpt" / "last.ckpt", weights_only=False)["global_step"] == 6
    assert checkpoint.best_model_path.endswith("epoch=0-step=2.ckpt")
