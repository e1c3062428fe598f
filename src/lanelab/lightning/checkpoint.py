"""Checkpoints that are safe to resume from: never of NaN or inf weights, and ``last.ckpt`` always
the newest state.

:class:`LaneCheckpoint` is Lightning's ModelCheckpoint (conf/callbacks/model_checkpoint.yaml
sets it up) that refuses, with a warning naming the file and the step, to write weights holding
NaN or inf, and that saves ``last.ckpt`` after every validation (Lightning saves it only with a
new top-k checkpoint, so a run past its best validation would leave ``last`` at the best) and
when training ends (max_steps, max_time, a signal or an error: ``save_on_exception``), so that a
resumed run starts where the previous one stopped.
:class:`~lanelab.lightning.LaneDetectionModule` refuses such weights on its side too, on saving
and on loading (:func:`non_finite_tensors`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import lightning.pytorch as pl
import torch
from lightning.pytorch.callbacks import ModelCheckpoint
from lightning.pytorch.trainer.states import TrainerFn
from lightning.pytorch.utilities import rank_zero_warn


def non_finite_tensors(state: Mapping[str, Any]) -> list[str]:
    """The names of the floating-point tensors of a state dict that hold NaN or inf."""
    return [
        name for name, value in state.items()
        if isinstance(value, torch.Tensor) and value.is_floating_point() and not bool(torch.isfinite(value).all())
    ]  # fmt: skip


def describe(names: list[str]) -> str:
    """'N tensors (a, b, c, ...)': non-finite tensors named in a message."""
    return f"{len(names)} tensors ({', '.join(names[:3])}{', ...' if len(names) > 3 else ''})"


class LaneCheckpoint(ModelCheckpoint):
    """ModelCheckpoint that never writes non-finite weights and keeps ``last`` at the newest state."""

    def _save_checkpoint(self, trainer: pl.Trainer, filepath: str) -> None:
        names = non_finite_tensors(trainer.lightning_module.state_dict())
        if names:
            rank_zero_warn(f"not saving {filepath} at step {trainer.global_step}: NaN or inf weights in {describe(names)}")
            return
        super()._save_checkpoint(trainer, filepath)

    def on_validation_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        super().on_validation_end(trainer, pl_module)
        if not self._should_save_on_train_epoch_end(trainer):
            self._save_last_if_behind(trainer)

    def on_train_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        super().on_train_epoch_end(trainer, pl_module)
        if self._should_save_on_train_epoch_end(trainer):  # no validation: the epoch's end stands for it
            self._save_last_if_behind(trainer)

    def on_train_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._save_last_if_behind(trainer)

    def on_exception(self, trainer: pl.Trainer, pl_module: pl.LightningModule, exception: BaseException) -> None:
        """Save ``last`` alone, without a line: Lightning also writes an epoch/step file that no
        top-k keeps (one more per stop of a preempted job), and the tools say where the state is."""
        if self._should_save_on_exception(trainer):
            self._save_last_checkpoint(trainer, self._monitor_candidates(trainer))

    def _save_last_if_behind(self, trainer: pl.Trainer) -> None:
        """Save ``last`` unless the last checkpoint written holds this very step (Lightning then
        wrote ``last`` with it)."""
        if (self.save_last and not trainer.fast_dev_run and not trainer.sanity_checking
                and trainer.state.fn == TrainerFn.FITTING and self._last_global_step_saved != trainer.global_step):
            self._save_last_checkpoint(trainer, self._monitor_candidates(trainer))
