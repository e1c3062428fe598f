"""The writers' lock of a clip store: one writing process at a time.

:func:`lock_store` takes the folder lock of :mod:`lanelab.folder_lock` on ``<store>/.lock``
(an exclusive ``flock`` naming its owner: pid, host, start time, command line); a second
writer fails at once with :class:`StoreBusy`, naming the store and that owner. The lock dies
with its process (a crash or ``kill -9`` leaves no stale lock) and is released when the file
is closed. Readers never take it: they see a manifest that lists only written clips.
"""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

from lanelab.folder_lock import FolderBusy, lock_folder

LOCK_NAME = ".lock"  # hidden: pyarrow, DuckDB and Spark skip it when reading the store


class StoreBusy(ValueError):
    """Another process is writing the store; the message names the store and that process."""


def lock_path(store_dir: str | Path) -> Path:
    """``<store_dir>/.lock``."""
    return Path(store_dir) / LOCK_NAME


def lock_store(store_dir: str | Path) -> TextIO:
    """Take the store's writers' lock (creating the store directory); return the open lock
    file, which holds it until closed. Raises :class:`StoreBusy` when another process has it."""
    try:
        return lock_folder(store_dir, LOCK_NAME)
    except FolderBusy as busy:
        raise StoreBusy(f"{Path(store_dir)} is being written by another writer ({busy.owner}); wait for it to "
                        "finish or write to another output") from None
