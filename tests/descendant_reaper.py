"""A pytest plugin: no process that a test run started outlives the run, Ctrl-C included.

``subprocess.run`` answers Ctrl-C by killing its child with SIGKILL, which leaves the child's own
children (a tool's pool workers, DDP ranks) running with no parent. On Linux this plugin makes the
pytest process the *child subreaper* of its descendants, so that such orphans are re-parented to
pytest instead of to init, and when the pytest process exits, however the session ended, it kills
every descendant still running: at exit rather than at the session's end, because libraries' exit
handlers (wandb's) still talk to their service processes then. Tools make their workers die with
them too (:mod:`lanelab.child_processes`); this catches whatever else a test leaves behind.

tests/conftest.py loads it for the suite; ``pytest -p descendant_reaper`` loads it elsewhere.
"""

from __future__ import annotations

import atexit
import os
import signal
import time
from multiprocessing import resource_tracker
from pathlib import Path

import pytest

from lanelab.child_processes import PR_SET_CHILD_SUBREAPER, prctl

KILL_ROUNDS = 5


def parents() -> dict[int, int]:
    """pid -> parent pid of every process (from /proc)."""
    found = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            found[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):  # it ended while we read
            continue
    return found


def descendants(pid: int) -> set[int]:
    """The pids of the processes below ``pid``: its children, theirs, and so on."""
    children: dict[int, list[int]] = {}
    for child, parent in parents().items():
        children.setdefault(parent, []).append(child)
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def kill_descendants() -> None:
    """SIGKILL every descendant of this process still running. The multiprocessing resource
    tracker is spared: it leaves when this process does, after cleaning up what it tracks."""
    spared = {getattr(resource_tracker._resource_tracker, "_pid", None)}
    for _ in range(KILL_ROUNDS):  # a child may have forked between the listing and its kill
        running = {pid for pid in descendants(os.getpid()) - spared if alive(pid)}
        if not running:
            return
        for pid in running:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                continue
        time.sleep(0.05)


def pytest_configure(config: pytest.Config) -> None:
    prctl(PR_SET_CHILD_SUBREAPER, 1)
    atexit.register(kill_descendants)  # registered first, so it runs after the handlers of what the tests import
