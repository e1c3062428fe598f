"""A run folder belongs to one ``lanelab-train`` process.

:class:`RunFolderLock`, a Hydra callback (``conf/hydra/default.yaml``), takes the folder lock of
:mod:`lanelab.folder_lock` on ``<run folder>/.lock`` before Hydra writes anything there
(``.hydra/``, ``train.log``; for ``--multirun``, on the sweep's folder). A second lanelab-train
into the same folder exits at once with status 2 and one line naming the folder and the process
that holds it; so does a run folder that cannot be written. The lock dies with its process, so a
run resumed in the folder (``ckpt_path=last``) once the first has ended takes it again.

The extra processes of a multi-process run share rank zero's folder and take no lock:
Lightning's DDP re-runs the command line with ``LOCAL_RANK`` set, torchrun sets ``RANK``, SLURM
``SLURM_PROCID``.
"""

from __future__ import annotations

import os
import sys
from typing import Any, TextIO

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from lanelab.config_checks import BAD_OPTION_STATUS, ConfigError, check_writable_folder
from lanelab.folder_lock import FolderBusy, lock_folder

LOCK_NAME = ".lock"
TOOL = "lanelab-train"
RANK_VARIABLES = ("RANK", "LOCAL_RANK", "SLURM_PROCID")


class RunFolderLock(Callback):
    """Holds the run folder's lock (the sweep folder's under --multirun) for the whole run."""

    def __init__(self) -> None:
        self._lock: TextIO | None = None

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._take("hydra.run.dir", config.hydra.run.dir)

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._take("hydra.sweep.dir", config.hydra.sweep.dir)

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._release()

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._release()

    def _take(self, key: str, folder: str) -> None:
        """Lock folder, or end the process with one line: Hydra turns a callback's exception into a warning."""
        if secondary_process():
            return
        try:
            check_writable_folder(key, folder)
            self._lock = lock_folder(folder, LOCK_NAME)
        except ConfigError as err:
            _exit(f"bad option: {err}")
        except FolderBusy as busy:
            _exit(f"{key}={folder} is the run folder of another lanelab-train ({busy.owner}); wait for it to end "
                  "or choose another folder")

    def _release(self) -> None:
        if self._lock is not None:
            self._lock.close()
            self._lock = None


def secondary_process() -> bool:
    """Whether this process is one of a multi-process run's other than rank zero."""
    return any(os.environ.get(name, "0").strip() not in ("", "0") for name in RANK_VARIABLES)


def _exit(message: str) -> None:
    print(f"{TOOL}: {message}", file=sys.stderr)
    sys.exit(BAD_OPTION_STATUS)
