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
    assert [Path(r.split()[2]).name for r in refusals] == ["epoch=0-step=2.ckpt", "last.ckpt", "last.ckpt"]  # the step, then the end
    assert all(" at step 2: NaN or inf weights in 1 tensors (net." in r for r in refusals)
    last = torch.load(tmp_path / "ckpt" / "last.ckpt", weights_only=False)
    assert last["global_step"] == 1  # the last finite weights
    assert all(torch.isfinite(v).all() for v in last["state_dict"].values() if v.is_floating_point())
    with pytest.raises(NonFiniteError, match="not saving a checkpoint of NaN or inf weights in 1 tensors"):
        trainer.save_checkpoint(tmp_path / "by_hand.ckpt")
    assert not (tmp_path / "by_hand.ckpt").exists()
