"""Worker processes that never outlive the run that started them.

A tool killed with SIGKILL (a test harness that times out, ``subprocess.run`` interrupted by
Ctrl-C, ``kill -9``) cannot clean up after itself; its pool workers would run on with no
parent. :func:`die_with_parent`, called first thing in a worker, makes the worker exit when its
parent does: Linux's ``prctl(PR_SET_PDEATHSIG, SIGKILL)``, elsewhere a thread that watches the
parent's pid. :func:`kill_pool` ends a pool at once, busy workers included, where waiting for
their jobs (``shutdown(wait=True)``) would hold an interrupted run for minutes.
"""

from __future__ import annotations

import ctypes
import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor

PR_SET_PDEATHSIG = 1  # linux/prctl.h
PR_SET_CHILD_SUBREAPER = 36
WATCH_S = 0.5  # how often the fallback thread looks for its parent


def prctl(option: int, value: int) -> bool:
    """Linux's ``prctl(option, value)`` for this process (or thread); False where it failed or
    there is none (not Linux)."""
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(option, value, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def die_with_parent(parent_pid: int) -> None:
    """Make this process exit when the process ``parent_pid`` (its parent) does."""
    if not prctl(PR_SET_PDEATHSIG, signal.SIGKILL):
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(WATCH_S)
    os._exit(1)


def init_worker(parent_pid: int) -> None:
    """A pool worker's start: Ctrl-C is its parent's to handle (the whole foreground process
    group gets it), and it dies with that parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


def kill_pool(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's workers, idle or busy, and shut it down without waiting for their jobs."""
    for process in list((pool._processes or {}).values()):
        process.kill()
    pool.shutdown(wait=True, cancel_futures=True)
