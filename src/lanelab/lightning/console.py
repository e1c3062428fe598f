"""What a run shows on the console: the progress bar, the model summary, and Lightning's lines
worth reading, once each.

- :class:`ProgressBar`: Rich's bar with what the module logs with ``prog_bar=True`` (the
  training loss, the last and best validation F1), without Lightning's ``v_num`` (a logger's
  version: a W&B run id says nothing there);
- :class:`ProgressLines`: the same as plain log lines, each tenth of an epoch or every 30 s and
  after each validation, for output that is no terminal (:func:`progress_bar` picks);
- :class:`ModelSummary`: Lightning's layer table through its logger (so it reaches the console
  and ``<run>/train.log`` alike), without the FLOPs column, which Lightning fills with 0 unless
  the module has an ``example_input_array`` (a batch of lanelab is a dict: none);
- :class:`DropNoise`: a logging filter for Lightning's lines that say nothing to a lanelab
  user (its advertisement, a note on the summary callback, one on estimating the steps);
- :func:`route_lightning_logs`: Lightning's loggers through the root logger's handlers only.
  Lightning adds a console handler of its own to ``lightning`` (and to ``lightning.pytorch`` /
  ``lightning.fabric`` when the root logger has none at import), so that a tool whose root logger
  prints would print each line twice;
- :func:`ignore_known_warnings`: warnings of the installed versions that no user setting
  changes (a deprecation inside Lightning's own code).
"""

from __future__ import annotations

import logging
import sys
import time
import warnings
from typing import Any

import lightning.pytorch as pl
from lightning.pytorch.callbacks import ModelSummary as LightningModelSummary
from lightning.pytorch.callbacks import ProgressBar as LightningProgressBar
from lightning.pytorch.callbacks import RichProgressBar
from lightning.pytorch.utilities.model_summary.model_summary import _format_summary_table

from lanelab.progress import LineTimer, countable, is_terminal

LIGHTNING_LOGGERS = ("lightning", "lightning.pytorch", "lightning.fabric")
NOISE = (
    "💡 Tip:",  # an advertisement for a hosted logger
    "Trainer already configured with model summary callbacks",  # lanelab's summary is the one asked for
    "Loading `train_dataloader` to estimate number of stepping batches",
)
KNOWN_WARNINGS = (
    # Lightning 2.6 calls a torch.utils._pytree API that torch 2.13 deprecates.
    r"`isinstance\(treespec, LeafSpec\)` is deprecated",
)

log = logging.getLogger(__name__)


class ProgressBar(RichProgressBar):
    """Rich's progress bar without ``v_num``."""

    def get_metrics(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> dict[str, Any]:
        metrics = super().get_metrics(trainer, pl_module)
        metrics.pop("v_num", None)
        return metrics


class ProgressLines(LightningProgressBar):
    """Training progress as log lines (:class:`lanelab.progress.LineTimer` says when):
    ``epoch 1/10, step 30/60 (50 %), train/loss 1.23, 12 s``; after each validation its metrics."""

    def __init__(self) -> None:
        super().__init__()
        self._enabled, self._timer, self._start = True, LineTimer(None), time.monotonic()

    def disable(self) -> None:
        self._enabled = False

    def enable(self) -> None:
        self._enabled = True

    def on_train_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._timer = LineTimer(self.total_train_batches)

    def on_train_batch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule, outputs: Any, batch: Any,
                           batch_idx: int) -> None:  # fmt: skip
        if not (self._enabled and trainer.is_global_zero and self._timer.due(batch_idx + 1)):
            return
        total = countable(self.total_train_batches)
        epochs = f"/{trainer.max_epochs}" if trainer.max_epochs and trainer.max_epochs > 0 else ""
        batches = f"/{total} ({100 * (batch_idx + 1) / total:.0f} %)" if total is not None else ""
        log.info("epoch %d%s, step %d%s%s, %.0f s", trainer.current_epoch + 1, epochs, batch_idx + 1, batches,
                 self._metrics(trainer, pl_module, "train/"), time.monotonic() - self._start)  # fmt: skip

    def on_validation_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if self._enabled and trainer.is_global_zero and not trainer.sanity_checking:
            log.info("validation after step %d%s", trainer.global_step, self._metrics(trainer, pl_module, "val/"))

    def _metrics(self, trainer: pl.Trainer, pl_module: pl.LightningModule, prefix: str) -> str:
        metrics = self.get_metrics(trainer, pl_module)
        return "".join(f", {name} {value:.4g}" if isinstance(value, float) else f", {name} {value}"
                       for name, value in metrics.items() if name.startswith(prefix))  # fmt: skip


def progress_bar(refresh_rate: int = 1, leave: bool = False) -> LightningProgressBar:
    """The training's progress: Rich's bar (:class:`ProgressBar`, these options) where stdout
    is a terminal, else :class:`ProgressLines`."""
    return ProgressBar(refresh_rate=refresh_rate, leave=leave) if is_terminal(sys.stdout) else ProgressLines()


class ModelSummary(LightningModelSummary):
    """Lightning's model summary, logged; the FLOPs column and total only when they were counted."""

    @staticmethod
    def summarize(
        summary_data: list[tuple[str, list[str]]],
        total_parameters: int,
        trainable_parameters: int,
        model_size: float,
        total_training_modes: dict[str, int],
        total_flops: int,
        **summarize_kwargs: Any,
    ) -> None:
        if not total_flops:
            summary_data = [column for column in summary_data if column[0] != "FLOPs"]
        table = _format_summary_table(total_parameters, trainable_parameters, model_size, total_training_modes,
                                      total_flops, *summary_data)  # fmt: skip
        if not total_flops:
            table = "\n".join(line for line in table.splitlines() if not line.lower().endswith("total flops"))
        log.info("\n%s", table)


class DropNoise(logging.Filter):
    """Drops the log records whose message starts with one of :data:`NOISE`."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(NOISE)


def route_lightning_logs() -> None:
    """Lightning's log lines through the root logger's handlers alone, which drop :data:`NOISE`;
    nothing changes while the root logger has no handler (a library use: Lightning prints)."""
    root = logging.getLogger()
    if not root.handlers:
        return
    for name in LIGHTNING_LOGGERS:
        logger = logging.getLogger(name)
        for handler in list(logger.handlers):
            logger.removeHandler(handler)
        logger.propagate = True
    for handler in root.handlers:
        if not any(isinstance(f, DropNoise) for f in handler.filters):
            handler.addFilter(DropNoise())


def ignore_known_warnings() -> None:
    """Ignore :data:`KNOWN_WARNINGS` in this process."""
    for pattern in KNOWN_WARNINGS:
        warnings.filterwarnings("ignore", message=pattern)

