"""SIGTERM (a scheduler's stop) ends lanelab-train after the step with last.ckpt saved, one line
saying where and how to resume, and status 143, never 0; ckpt_path=last resumes from it."""

import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
import torch
from test_train_resume import logged_steps
from train_command import run, train_command


def wait_for_a_step(process: subprocess.Popen, metrics_csv: Path, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not (metrics_csv.is_file() and logged_steps(metrics_csv)):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no training step logged"
        time.sleep(0.2)


@pytest.mark.slow
def test_sigterm_saves_last_says_where_exits_143_and_resumes(tiny_store: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    process = subprocess.Popen(train_command(tiny_store, run_dir, "trainer.max_epochs=50"),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    wait_for_a_step(process, run_dir / "csv" / "metrics.csv")
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 143  # old code: 0, as if the run had finished
    last = run_dir / "checkpoints" / "last.ckpt"
    stopped = re.search(rf"lanelab-train: stopped by SIGTERM at step (\d+) \(epoch \d+\); the state is saved in "
                        rf"{re.escape(str(last))}; resume with the same command and hydra.run.dir={re.escape(str(run_dir))} "
                        "ckpt_path=last\n", stderr)  # fmt: skip
    assert stopped, stderr
    step = int(stopped.group(1))
    assert torch.load(last, weights_only=False)["global_step"] == step
    assert [p.name for p in (run_dir / "checkpoints").iterdir()] == ["last.ckpt"]  # no stray epoch/step file

    resumed = run(train_command(tiny_store, run_dir, "trainer.max_epochs=50", f"trainer.max_steps={step + 2}",
                                "ckpt_path=last"))  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert torch.load(last, weights_only=False)["global_step"] == step + 2
    assert logged_steps(run_dir / "csv" / "metrics.csv") == list(range(step + 2))  # each step once
