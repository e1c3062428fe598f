"""lanelab's WandbLogger starts an offline W&B run without wandb's deprecation warning about the
``anonymous`` setting that Lightning's own always passes, and without wandb's banner and summary."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

START_A_RUN = """
import sys
from {module} import WandbLogger
logger = WandbLogger(project="lanelab", save_dir=sys.argv[1], offline=True)
logger.log_metrics({{"x": 1.0}}, step=0)
logger.experiment.finish()
"""


def start_a_run(module: str, folder: Path) -> str:
    env = {**os.environ, "WANDB_MODE": "offline"}
    env.pop("WANDB_SILENT", None)
    result = subprocess.run([sys.executable, "-c", START_A_RUN.format(module=module), str(folder)],
                            capture_output=True, text=True, timeout=120, env=env, check=False)  # fmt: skip
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout + result.stderr


@pytest.mark.slow
def test_no_anonymous_warning(tmp_path: Path) -> None:
    assert "anonymous setting" in start_a_run("lightning.pytorch.loggers", tmp_path / "lightning")  # what it replaces
    output = start_a_run("lanelab.lightning.wandb_logger", tmp_path / "lanelab")
    assert "anonymous setting" not in output
    assert list((tmp_path / "lanelab" / "wandb").glob("offline-run-*"))


def test_an_offline_run_keeps_its_files_without_wandbs_banner(tmp_path: Path) -> None:
    assert "Tracking run with wandb" in start_a_run("lightning.pytorch.loggers", tmp_path / "lightning")
    output = start_a_run("lanelab.lightning.wandb_logger", tmp_path / "lanelab")
    assert [line for line in output.splitlines() if line.startswith("wandb:") and "WARNING" not in line] == []
    (run,) = (tmp_path / "lanelab" / "wandb").glob("offline-run-*")
    assert list(run.glob("*.wandb"))  # the run's data, for `wandb sync`
