"""Every tool's surface: --help shows the tool's own options, and an option it does not have ends
in one line naming it with exit status 2 (Hydra's composition errors included, not only lanelab's
own checks)."""

from __future__ import annotations

import os
import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOOLS = {  # tool -> (module, an option of its own)
    "lanelab-synth": ("data_ingest.synth.cli", "duration_s"),
    "lanelab-ingest": ("data_ingest.ingest.cli", "split"),
    "lanelab-eval": ("lanelab.experiment.eval_cli", "test_list"),
    "lanelab-openlane": ("data_ingest.openlane.cli", "scene_tags"),
    "lanelab-once": ("data_ingest.once.cli", "poses"),
    "lanelab-train": ("lanelab.experiment.train", "ckpt_path"),
    "lanelab-predict": ("log_predict.cli", "preview_frames"),
    "lanelab-export": ("lanelab.deploy.export_cli", "batch_size"),
}


def run(module: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}", "WANDB_MODE": "offline"}
    return subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True, timeout=120,
                          env=env, cwd=cwd, check=False)  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_help_shows_the_tools_own_options(tool: str) -> None:
    module, option = TOOLS[tool]
    result = run(module, "--help")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(tool) and f"\n{option}:" in result.stdout
    if tool == "lanelab-train":
        assert "debug: default, fast_dev_run, limit, overfit" in result.stdout
    else:  # the training groups are not this tool's
        assert "model/backbone" not in result.stdout and "experiment:" not in result.stdout


@pytest.mark.slow
def test_demo_help_without_a_traceback() -> None:
    result = run("lanelab.demo", "--help")
    assert result.returncode == 0 and result.stderr == ""
    assert result.stdout.startswith("``lanelab-demo``") and "demo.out=DIR" in result.stdout


@pytest.mark.slow
@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_an_unknown_option_is_one_line_and_exit_2(tool: str, tmp_path: Path) -> None:
    """Hydra's own refusal (exit 1, several lines before) now reads like lanelab's of +typo=1."""
    result = run(TOOLS[tool][0], "typo=1", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr == f"{tool}: bad option: typo: no such option (check its spelling in the tool's conf/*.yaml)\n"


# The presets Hydra offers for a misspelt experiment, as the installed package holds them.
EXPERIMENTS = sorted(path.name.removesuffix(".yaml") for path in (files("lanelab.conf") / "experiment").iterdir()
                     if path.name.endswith(".yaml"))  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["seed=abc"], "lanelab-train: bad option: seed: Value 'abc' of type 'str' could not be converted to Integer\n"),
        (["experiment=tinyy"], "lanelab-train: bad option: In 'train': Could not find 'experiment/tinyy' (choices: "
                               f"{', '.join(EXPERIMENTS)})\n"),
    ],
)
def test_hydra_errors_are_one_line_and_exit_2(args: list[str], message: str, tmp_path: Path) -> None:
    result = run("lanelab.experiment.train", *args, cwd=tmp_path)
    assert (result.returncode, result.stderr) == (2, message)
