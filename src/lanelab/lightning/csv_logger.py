"""Lightning's CSVLogger, but a run that logs into a folder that already holds a ``metrics.csv``
(a resumed run) appends its rows to it instead of deleting it."""

from __future__ import annotations

import csv
import os

from lightning.pytorch.loggers import csv_logs
from lightning.pytorch.loggers.logger import rank_zero_experiment


class AppendingWriter(csv_logs.ExperimentWriter):
    """Lightning's writer that keeps an existing ``metrics.csv`` and its columns."""

    def _check_log_dir_exists(self) -> None:
        """Read the columns of the existing file (Lightning's own deletes the file here)."""
        if self._fs.isfile(self.metrics_file_path):
            with self._fs.open(self.metrics_file_path, "r", newline="") as file:
                self.metrics_keys = next(csv.reader(file), [])


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
