"""The writers' lock of a clip store: one writing process at a time.

:func:`lock_store` takes an exclusive ``flock`` on ``<store>/.lock`` and writes its owner
(pid, host, start time, command line) into it; a second writer fails at once with
:class:`StoreBusy`, naming the store and that owner. The lock belongs to the open file: it
dies with its process (a crash or ``kill -9`` leaves no stale lock) and is released when the
file is closed. Readers never take it: they see a manifest that lists only written clips.
"""

from __future__ import annotations

import fcntl
import os
import socket
import sys
import time
from pathlib import Path
from typing import TextIO

LOCK_NAME = ".lock"  # hidden: pyarrow, DuckDB and Spark skip it when reading the store


class StoreBusy(ValueError):
    """Another process is writing the store; the message names the store and that process."""


def lock_path(store_dir: str | Path) -> Path:
    """``<store_dir>/.lock``."""
    return Path(store_dir) / LOCK_NAME


def lock_store(store_dir: str | Path) -> TextIO:
    """Take the store's writers' lock (creating the store directory); return the open lock
    file, which holds it until closed. Raises :class:`StoreBusy` when another process has it."""
    path = lock_path(store_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle = open(path, "a+", encoding="utf-8")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        owner = handle.read().strip() or "owner not yet recorded"
        handle.close()
        raise StoreBusy(f"{Path(store_dir)} is being written by another writer ({owner}); wait for it to "
                        "finish or write to another output") from None
    handle.seek(0)
    handle.truncate()
    handle.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}: "
                 f"{' '.join([Path(sys.argv[0]).name, *sys.argv[1:]])}\n")
    handle.flush()
    return handle
