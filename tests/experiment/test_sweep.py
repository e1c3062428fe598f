"""A 2-job multirun of the tiny config (basic launcher) and its lanelab-sweep-report."""

import csv
import subprocess
import sys
from pathlib import Path

from lanelab.experiment.sweep_report import PLOT_PNG, REPORT_CSV, REPORT_MD, main

SWEEPS = Path(__file__).resolve().parents[2] / "sweeps"


def test_multirun_and_report(tiny_store: Path, tmp_path: Path) -> None:
    multirun = tmp_path / "multirun"
    command = [
        sys.executable, "-m", "lanelab.experiment.train", "--multirun", f"--config-dir={SWEEPS}",
        "--config-name=memory_length", "experiment=tiny", f"data.store={tiny_store}", "logger=none",
        "trainer.max_epochs=1", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1",
        "model.net.num_memory_frames=0,2", f"hydra.sweep.dir={multirun}",
    ]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]

    main([str(multirun)])
    with (multirun / REPORT_CSV).open() as f:
        rows = list(csv.DictReader(f))
    assert [row["model.net.num_memory_frames"] for row in rows] == ["0", "2"]
    assert {"f1", "precision", "recall", "x_error_close", "x_error_far", "z_error_close", "z_error_far"} <= set(rows[0])
    assert "| model.net.num_memory_frames | F1 (%) |" in (multirun / REPORT_MD).read_text()
    assert (multirun / PLOT_PNG).stat().st_size > 0
