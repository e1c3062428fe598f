"""lanelab's WandbLogger starts an offline W&B run without wandb's deprecation warning about the
``anonymous`` setting that Lightning's own always passes, and without wandb's banner and summary."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # each run is a Python process that imports Lightning and wandb

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


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[str, Path]]:
    """What an offline run started with Lightning's WandbLogger and with lanelab's prints, and
    the folder it saves to: each started once for the tests below."""
    root = tmp_path_factory.mktemp("wandb_runs")
    modules = {"lightning": "lightning.pytorch.loggers", "lanelab": "lanelab.lightning.wandb_logger"}
    return {name: (start_a_run(module, root / name), root / name) for name, module in modules.items()}


def test_no_anonymous_warning(runs: dict[str, tuple[str, Path]]) -> None:
    assert "anonymous setting" in runs["lightning"][0]  # what it replaces
    output, folder = runs["lanelab"]
    assert "anonymous setting" not in output
    assert list((folder / "wandb").glob("offline-run-*"))


def test_an_offline_run_keeps_its_files_without_wandbs_banner(runs: dict[str, tuple[str, Path]]) -> None:
    assert "Tracking run with wandb" in runs["lightning"][0]
    output, folder = runs["lanelab"]
    assert [line for line in output.splitlines() if line.startswith("wandb:") and "WARNING" not in line] == []
    (run,) = (folder / "wandb").glob("offline-run-*")
    assert list(run.glob("*.wandb"))  # the run's data, for `wandb sync`
