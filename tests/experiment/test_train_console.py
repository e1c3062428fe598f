"""What a user sees of a training run: the run folder first, a closing table, the same lines in
<run>/train.log, Lightning's lines once and without noise; the loggers get the learning rate,
the best val F1 and the pictures (CSV beside W&B too), and a resumed run logs on as the same W&B run."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest
from tiny_store import tiny_overrides

from lanelab.experiment.run_names import swept_keys

ROOT = Path(__file__).resolve().parents[2]


def lanelab_train(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}", "WANDB_MODE": "offline",
           "WANDB_SILENT": "true", "COLUMNS": "200"}  # fmt: skip
    command = [sys.executable, "-m", "lanelab.experiment.train", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=240, env=env, check=False)


@pytest.mark.slow
def test_console_log_file_and_loggers_of_a_run_and_its_resume(tiny_store: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    args = [*tiny_overrides(tiny_store, run)[:-1], "logger=[csv,wandb]", "trainer.max_epochs=1", "test=true",
            f"hydra.run.dir={run}"]  # fmt: skip
    first = lanelab_train(*args)
    assert first.returncode == 0, first.stderr[-3000:]
    out = first.stdout
    assert out.startswith(f"lanelab-train: run folder {run}\n")
    closing = out[out.index("lanelab-train: done"):].splitlines()
    assert [line.split()[0] for line in closing[1:7]] == ["run", "best", "best", "steps", "test", "time"]
    assert closing[2].endswith(".ckpt") and closing[3].endswith("%") and closing[5].endswith("%")
    for noise in ("FLOPs", "Flops", "💡", "Trainer already configured", "LeafSpec", "v_num"):
        assert noise not in out + first.stderr, noise
    assert out.count("GPU available: False, used: False") == 1

    log = (run / "train.log").read_text()
    assert "lanelab-train: run folder" in log and "lanelab-train: done" in log and "Total params" in log

    rows = list(csv.DictReader((run / "csv" / "metrics.csv").open()))
    assert any(row.get("lr-AdamW/pg1") for row in rows) and any(row.get("val/f1_best") for row in rows)
    assert any((run / "csv" / "pictures").glob("val_pictures_step*.png"))  # CSV beside W&B gets its pictures

    resumed = lanelab_train(*args, "ckpt_path=last", "trainer.max_epochs=2")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    runs = sorted((run / "wandb").glob("offline-run-*"))
    assert len(runs) == 2 and len({path.name.rsplit("-", 1)[1] for path in runs}) == 1  # one W&B run id


def test_a_sweep_job_is_named_by_what_its_sweep_varies() -> None:
    argv = ["experiment=tiny", "model.net.num_memory_frames=0,3", "+attention=global,sla", "seed=1"]
    assert swept_keys(argv, {}) == {"model.net.num_memory_frames", "attention"}
    assert swept_keys(["hydra/launcher=joblib"], {"model.net.tca_neighbors": "1,5"}) == {"model.net.tca_neighbors"}
