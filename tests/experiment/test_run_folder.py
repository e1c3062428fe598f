"""A run folder belongs to one lanelab-train: a second one into it exits at once with status 2 and
one line naming the process that holds it, writing nothing there; once that process has ended, a
run resumes in the folder. A run folder that cannot be written is one line too."""

import os
from pathlib import Path

import pytest
from omegaconf import OmegaConf
from train_command import read_only, run, train_command

from lanelab.experiment.run_folder import LOCK_NAME, RunFolderLock
from lanelab.folder_lock import lock_folder

ONE_STEP = ["trainer.max_epochs=1", "trainer.limit_train_batches=1", "trainer.limit_val_batches=1"]


@pytest.mark.slow
def test_a_second_run_into_a_folder_in_use_fails_naming_its_pid(tiny_store: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "same"
    first = lock_folder(run_dir, LOCK_NAME)  # as a lanelab-train running there holds it
    second = run(train_command(tiny_store, run_dir, *ONE_STEP))
    assert second.returncode == 2  # old code: 0, both runs writing the folder
    (line,) = second.stderr.strip().splitlines()
    assert line.startswith(f"lanelab-train: hydra.run.dir={run_dir} is the run folder of another lanelab-train "
                           f"(pid {os.getpid()} on ")  # fmt: skip
    assert [p.name for p in run_dir.iterdir()] == [LOCK_NAME]  # no .hydra, train.log, checkpoints or metrics

    first.close()  # the first run ended: its folder can be resumed in
    resumed = run(train_command(tiny_store, run_dir, *ONE_STEP, "ckpt_path=last"))
    assert resumed.returncode == 0, resumed.stderr
    assert (run_dir / "checkpoints" / "last.ckpt").is_file()


def test_the_other_processes_of_a_multi_process_run_share_its_folder(tmp_path: Path, monkeypatch) -> None:
    first = lock_folder(tmp_path, LOCK_NAME)  # rank zero's
    monkeypatch.setenv("LOCAL_RANK", "1")  # as Lightning's DDP starts the others
    callback = RunFolderLock()
    callback.on_run_start(OmegaConf.create({"hydra": {"run": {"dir": str(tmp_path)}}}))  # no exit: no lock taken
    callback.on_run_end(OmegaConf.create({}))
    first.close()


@pytest.mark.slow
def test_a_run_folder_that_cannot_be_written_is_one_line(tiny_store: Path, tmp_path: Path) -> None:
    locked = tmp_path / "read_only"
    result = run(read_only(locked, train_command(tiny_store, locked / "run", *ONE_STEP)))
    assert result.returncode == 2, result.stderr  # old code: 1 and a traceback
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith(f"lanelab-train: bad option: hydra.run.dir={locked / 'run'}: cannot write there (")
