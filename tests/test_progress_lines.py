"""Progress where the output is no terminal (a file, a pipe): plain lines each tenth of the work or
every 30 s, never a bar of carriage returns; the same for training (Lightning) and no W&B banner."""

from __future__ import annotations

import io
import logging
import os
import subprocess
import sys
from pathlib import Path

import lightning.pytorch as pl
import pytest
from lightning.pytorch.demos.boring_classes import BoringModel

from lanelab.lightning.console import ProgressBar, ProgressLines, progress_bar
from lanelab.progress import LineTimer, Progress

ROOT = Path(__file__).resolve().parents[1]


def test_a_count_into_a_file_is_a_line_each_tenth() -> None:
    stream = io.StringIO()
    with Progress(1000, "lanelab-synth", "frames", stream=stream) as bar:
        for _ in range(1000):
            bar.update(1)
    text = stream.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and len(lines) == 10
    assert lines[0].startswith("lanelab-synth: 100/1000 frames (10 %), ")
    assert lines[-1].startswith("lanelab-synth: 1000/1000 frames (100 %), ")


def test_sizes_and_a_last_line_when_the_work_stops_short() -> None:
    stream = io.StringIO()
    with Progress(10_000_000, "lanelab-ingest", "B", unit_scale=True, stream=stream) as bar:
        bar.update(2_500_000)
        bar.update(400_000)  # 29 %: short of the next tenth, shown when the count closes
    lines = stream.getvalue().splitlines()
    assert [line.split(",")[0] for line in lines] == ["lanelab-ingest: 2.50M/10.0M B (25 %)",
                                                      "lanelab-ingest: 2.90M/10.0M B (29 %)"]  # fmt: skip


def test_without_a_total_a_line_every_interval() -> None:
    now = [0.0]
    timer = LineTimer(None, interval_s=30.0, clock=lambda: now[0])
    due = []
    for second in range(100):
        now[0] = float(second)
        due.append(timer.due(second))
    assert [second for second, is_due in enumerate(due) if is_due] == [30, 60, 90]


def test_lanelab_synth_into_a_file_prints_lines_not_a_bar(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    tiny = ["duration_s=2.0", "fps=5", "camera.width=160", "camera.height=120", "tf_rate_hz=20"]
    with open(tmp_path / "out.txt", "w") as out:  # stdout and stderr into one file, as `> out.txt 2>&1`
        result = subprocess.run([sys.executable, "-m", "data_ingest.synth.cli", f"output_dir={tmp_path / 'logs'}",
                                 "num_logs=1", *tiny], stdout=out, stderr=subprocess.STDOUT, env=env, timeout=300, check=False)  # fmt: skip
    data = (tmp_path / "out.txt").read_bytes()  # bytes: reading text would turn a "\r" into a newline
    assert result.returncode == 0, data.decode()
    assert b"\r" not in data
    progress = [line for line in data.decode().splitlines() if line.startswith("lanelab-synth: ")]
    assert len(progress) == 10 and progress[-1].startswith("lanelab-synth: 10/10 frames (100 %)")


def test_training_progress_is_log_lines_where_stdout_is_no_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture, caplog: pytest.LogCaptureFixture
) -> None:
    assert isinstance(progress_bar(), ProgressLines)  # pytest's captured stdout is no terminal
    trainer = pl.Trainer(default_root_dir=tmp_path, max_epochs=2, limit_train_batches=20, limit_val_batches=2,
                         callbacks=[ProgressLines()], logger=False, enable_checkpointing=False,
                         enable_model_summary=False, accelerator="cpu")  # fmt: skip
    with caplog.at_level(logging.INFO, logger="lanelab.lightning.console"):
        trainer.fit(BoringModel())
    lines = [record.getMessage() for record in caplog.records if record.name == "lanelab.lightning.console"]
    steps = [line for line in lines if line.startswith("epoch ")]
    assert len(steps) == 20 and steps[0].startswith("epoch 1/2, step 2/20 (10 %)")
    assert steps[-1].startswith("epoch 2/2, step 20/20 (100 %)")
    assert sum(line.startswith("validation after step ") for line in lines) == 2  # no line for the sanity check
    assert "\r" not in capsys.readouterr().out


def test_training_under_a_time_cap_logs_to_its_last_step(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """With max_time (the demo's cap) Lightning counts 0 batches at the last step: the line then
    has no percentage, and the run ends (it stopped with ZeroDivisionError once)."""
    trainer = pl.Trainer(default_root_dir=tmp_path, max_epochs=-1, max_steps=30, max_time="00:00:05:00",
                         val_check_interval=10, check_val_every_n_epoch=None, limit_val_batches=2,
                         callbacks=[ProgressLines()], logger=False, enable_checkpointing=False,
                         enable_model_summary=False, accelerator="cpu")  # fmt: skip
    with caplog.at_level(logging.INFO, logger="lanelab.lightning.console"):
        trainer.fit(BoringModel())
    assert trainer.global_step == 30
    lines = [record.getMessage() for record in caplog.records if record.name == "lanelab.lightning.console"]
    assert sum(line.startswith("validation after step ") for line in lines) == 3


def test_a_terminal_gets_the_rich_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys.stdout, "isatty", lambda: True, raising=False)
    assert isinstance(progress_bar(), ProgressBar)
