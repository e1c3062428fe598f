"""lanelab-sweep-report on jobs that never validated, on a sweep that learnt nothing, and on job
files it cannot read: named, with what to do, instead of a table without metrics, of zeros, or a
traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lanelab.experiment.sweep_report import REPORT_MD, write_report


def job(multirun: Path, number: int, value: int, metrics: str, *overrides: str) -> Path:
    folder = multirun / str(number)
    (folder / ".hydra").mkdir(parents=True)
    lines = [f"model.net.num_points={value}", "trainer.max_steps=5", *overrides]
    (folder / ".hydra" / "overrides.yaml").write_text("".join(f"- {line}\n" for line in lines))
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


@pytest.mark.parametrize("preset, why", [
    (["experiment=tiny"], "experiment=tiny is a smoke test"),
    ([], "the jobs trained too few steps to learn (at most 5)"),
])  # fmt: skip
def test_a_sweep_whose_every_f1_is_0_warns_and_names_the_recipe_that_learns(
    preset: list[str], why: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 38: the README's sweep of experiment=tiny reports F1 0.0 % in every row, silently."""
    zeros = json.dumps({"val/f1": 0.0, "val/precision": 0.0, "val/recall": 0.0, "train/steps": 5.0})
    job(tmp_path, 0, 10, zeros, *preset)
    job(tmp_path, 1, 20, zeros, *preset)
    write_report(tmp_path, tmp_path)
    warning = "every job's F1 is 0: no job found a lane."
    assert f"lanelab-sweep-report: warning: {warning} {why}" in capsys.readouterr().err
    report = (tmp_path / REPORT_MD).read_text()
    assert warning in report and "lanelab-train --multirun experiment=demo data.store=STORE" in report


def test_a_sweep_with_one_job_above_0_does_not_warn(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    job(tmp_path, 0, 10, json.dumps({"val/f1": 0.0}), "experiment=tiny")
    job(tmp_path, 1, 20, json.dumps({"val/f1": 0.01}), "experiment=tiny")
    write_report(tmp_path, tmp_path)
    assert "F1 is 0" not in capsys.readouterr().err + (tmp_path / REPORT_MD).read_text()


def test_a_single_tiny_run_with_f1_0_is_named_a_smoke_test(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No swept key: the table names the job by its folder, the warning still reads its preset."""
    job(tmp_path, 0, 10, json.dumps({"test/f1": 0.0, "val/f1": 0.2}), "experiment=tiny")
    write_report(tmp_path, tmp_path)
    assert "every job's F1 is 0: no job found a lane. experiment=tiny is a smoke test" in capsys.readouterr().err
