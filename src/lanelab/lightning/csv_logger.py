"""Lightning's CSVLogger, but a run that logs into a folder that already holds a ``metrics.csv``
(a resumed run) appends its rows to it instead of deleting it; and the history stays in step
with the checkpoints: a run resumed from a checkpoint first drops the rows that were logged
after that checkpoint was saved (by a run that went on and then crashed), which the resumed run
logs again (:class:`HistoryAtCheckpoint`)."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
from lightning.pytorch.loggers import csv_logs
from lightning.pytorch.loggers.logger import rank_zero_experiment

from lanelab.atomic_file import atomic_output


class AppendingWriter(csv_logs.ExperimentWriter):
    """Lightning's writer that keeps an existing ``metrics.csv`` and its columns, and counts its rows."""

    def _check_log_dir_exists(self) -> None:
        """Read the columns and count the rows of the existing file (Lightning's own deletes the file here)."""
        self.metrics_keys, rows = self._read()
        self._saved_count = len(rows)

    def _read(self) -> tuple[list[str], list[dict[str, str]]]:
        """The saved file's columns and rows (none without a file)."""
        if not self._fs.isfile(self.metrics_file_path):
            return [], []
        with self._fs.open(self.metrics_file_path, "r", newline="") as file:
            reader = csv.DictReader(file)
            rows = list(reader)
            return list(reader.fieldnames or []), rows

    def save(self) -> None:
        self._saved_count += len(self.metrics)
        super().save()

    def row_count(self) -> int:
        """Rows of the history so far, saved or still buffered."""
        return self._saved_count + len(self.metrics)

    def keep_first_rows(self, count: int) -> None:
        """Drop every row of the history after the first count."""
        self.save()
        _, rows = self._read()
        if len(rows) <= count:
            return
        with atomic_output(Path(self.metrics_file_path)) as tmp, tmp.open("w", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=self.metrics_keys)
            writer.writeheader()
            writer.writerows(rows[:count])
        self._saved_count = count


class CSVLogger(csv_logs.CSVLogger):
    """``<save_dir>/<name>/<version>/metrics.csv`` and ``hparams.yaml``; rows of an earlier run in
    the same folder (the run this one resumes) are kept, the new ones appended."""

    @property
    @rank_zero_experiment
    def experiment(self) -> AppendingWriter:
        if self._experiment is None:
            self._fs.makedirs(self.root_dir, exist_ok=True)
            self._experiment = AppendingWriter(log_dir=os.fspath(self.log_dir))
        return self._experiment


class HistoryAtCheckpoint(pl.Callback):
    """Records in every checkpoint how many rows each CSV history held when it was saved
    (key ``csv_history_rows``: metrics file -> rows), and cuts those histories back to that when
    a run resumes from it."""

    KEY = "csv_history_rows"

    def __init__(self) -> None:
        self.resumed: dict[str, int] = {}

    def on_save_checkpoint(self, trainer: pl.Trainer, module: pl.LightningModule, checkpoint: dict[str, Any]) -> None:
        checkpoint[self.KEY] = {writer.metrics_file_path: writer.row_count() for writer in _writers(trainer)}

    def on_load_checkpoint(self, trainer: pl.Trainer, module: pl.LightningModule, checkpoint: dict[str, Any]) -> None:
        self.resumed = dict(checkpoint.get(self.KEY, {}))

    def on_train_start(self, trainer: pl.Trainer, module: pl.LightningModule) -> None:
        for writer in _writers(trainer):
            if writer.metrics_file_path in self.resumed:
                writer.keep_first_rows(self.resumed[writer.metrics_file_path])


def _writers(trainer: pl.Trainer) -> list[AppendingWriter]:
    """The writers of the trainer's CSV loggers (on rank zero; the other ranks write none)."""
    if not trainer.is_global_zero:
        return []
    return [logger.experiment for logger in trainer.loggers if isinstance(logger, CSVLogger)]
