"""lanelab-sweep-report on jobs that never validated, and on job files it cannot read: named,
with what to do, instead of a table without metrics or a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lanelab.experiment.sweep_report import REPORT_MD, write_report


def job(multirun: Path, number: int, value: int, metrics: str) -> Path:
    folder = multirun / str(number)
    (folder / ".hydra").mkdir(parents=True)
    (folder / ".hydra" / "overrides.yaml").write_text(f"- model.net.num_points={value}\n- trainer.max_steps=5\n")
    (folder / "metrics.json").write_text(metrics)
    return folder


def test_jobs_that_never_validated_are_named_with_the_way_to_validate(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    job(tmp_path, 0, 10, json.dumps({"train/loss": 3.0, "train/steps": 5.0}))
    job(tmp_path, 1, 20, json.dumps({"train/loss": 2.0, "train/steps": 5.0}))
    write_report(tmp_path, tmp_path)
    warning = "2 of 2 jobs never validated (0, 1)"
    assert f"lanelab-sweep-report: warning: {warning}" in capsys.readouterr().err
    report = (tmp_path / REPORT_MD).read_text()
    assert warning in report and "trainer.val_check_interval=N" in report


def test_an_unreadable_metrics_file_is_named_and_its_job_left_out(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    job(tmp_path, 0, 10, json.dumps({"val/f1": 0.5}))
    broken = job(tmp_path, 1, 20, "{cut")
    write_report(tmp_path, tmp_path)
    err = capsys.readouterr().err
    assert f"lanelab-sweep-report: {broken / 'metrics.json'}: cannot be read (" in err and "its job is left out" in err
    assert "| 0 | 50.0 |" in (tmp_path / REPORT_MD).read_text()  # one job left: the table names it by number
