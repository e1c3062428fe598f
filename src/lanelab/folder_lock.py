"""An exclusive lock on a folder, held by one process at a time.

:func:`lock_folder` takes an exclusive ``flock`` on a file in the folder and writes its owner
(pid, host, start time, command line) into it; a second process fails at once with
:class:`FolderBusy`, naming that owner. The lock belongs to the open file: it dies with its
process (a crash or ``kill -9`` leaves no stale lock to remove) and is released when the file
is closed. The clip store's writers (:mod:`lanelab.store.lock`) and ``lanelab-train``'s run
folders (:mod:`lanelab.experiment.run_folder`) use it.
"""

from __future__ import annotations

import fcntl
import os
import socket
import sys
import time
from pathlib import Path
from typing import TextIO


class FolderBusy(ValueError):
    """Another process holds the folder's lock; ``owner`` names it (pid, host, start time, command)."""

    def __init__(self, folder: Path, owner: str) -> None:
        super().__init__(f"{folder} is locked by another process ({owner})")
        self.folder, self.owner = folder, owner


def lock_folder(folder: str | Path, name: str) -> TextIO:
    """Take the lock ``<folder>/<name>`` (creating the folder); return the open lock file,
    which holds it until closed. Raises :class:`FolderBusy` when another process has it, and
    OSError when the folder cannot be written."""
    path = Path(folder) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = open(path, "a+", encoding="utf-8")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        owner = handle.read().strip() or "owner not yet recorded"
        handle.close()
        raise FolderBusy(Path(folder), owner) from None
    handle.seek(0)
    handle.truncate()
    handle.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}: "
                 f"{' '.join([Path(sys.argv[0]).name, *sys.argv[1:]])}\n")
    handle.flush()
    return handle
