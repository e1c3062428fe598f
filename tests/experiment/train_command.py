"""lanelab-train as a process, for the tests of what only a process shows: its exit status, its
lines on stderr, signals, a run folder shared by two processes, a folder it cannot write."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


def train_command(store: Path, run_dir: Path, *more: str) -> list[str]:
    """lanelab-train of the tiny experiment on store in the run folder run_dir, logging to CSV."""
    return [sys.executable, "-m", "lanelab.experiment.train", "experiment=tiny", f"data.store={store}",
            f"hydra.run.dir={run_dir}", "logger=csv", *more]  # fmt: skip


def eval_command(*options: str) -> list[str]:
    return [sys.executable, "-m", "lanelab.experiment.eval_cli", *options]


def run(command: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def read_only(folder: Path, command: list[str]) -> list[str]:
    """command, run where folder cannot be written: made read-only when this process is not root
    (root writes anyway), else bind-mounted read-only in a mount namespace of the command's own."""
    folder.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return command
    if shutil.which("unshare") is None or subprocess.run(["unshare", "-m", "true"], capture_output=True).returncode:
        pytest.skip("root without mount namespaces: no folder root cannot write")
    return ["unshare", "-m", "sh", "-c", 'mount --bind -o ro "$0" "$0" && exec "$@"', str(folder), *command]
