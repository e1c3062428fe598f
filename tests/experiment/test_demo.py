"""lanelab-demo end to end at a miniature scale: synthesize, ingest, train both models,
evaluate them on held-out drives, print and write the comparison."""

import os
from pathlib import Path

import pytest

from lanelab.demo import COMPARISON_MD, best_checkpoint, main

MINIATURE = [
    "demo.synth=['camera.width=96','camera.height=64','fps=5','workers=1']",
    "demo.train_logs=['num_logs=2','duration_s=2','seed=1']",
    "demo.test_logs.fog=['num_logs=1','duration_s=1','seed=101','world.weather=fog']",
    "demo.test_logs.traffic=['num_logs=1','duration_s=1','seed=102']",
    "demo.ingest_train=['split.by=clip','split.train=0.5','split.val=0.5','split.test=0.0','clips.max_length_s=0.4']",
    "data.image_size=[64,96]", "trainer.max_steps=2", "trainer.limit_val_batches=1", "evaluation.num_pictures=1",
]  # fmt: skip


def test_demo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    main([f"demo.out={tmp_path}", *MINIATURE])
    table = (tmp_path / COMPARISON_MD).read_text()
    assert "| sparselanestp |" in table and "| latr_baseline |" in table and "F1 fog (%)" in table
    assert "Where the F1 goes" in table and "| predictions | F1 (%) | near positions |" in table
    for model in ("sparselanestp", "latr_baseline"):
        assert (tmp_path / model / "heldout" / "pictures.png").is_file()
    assert "report and pictures in" in capsys.readouterr().out


def test_best_checkpoint_is_the_newest_best_of_a_folder_trained_into_again(tmp_path: Path) -> None:
    """A second demo run into the same folder keeps the first run's best file beside its own:
    the newest is evaluated, not whichever the file system lists first."""
    checkpoints = tmp_path / "checkpoints"
    checkpoints.mkdir()
    assert best_checkpoint(tmp_path) == checkpoints / "last.ckpt"  # no best yet
    for index, name in enumerate(["epoch002-step0001500.ckpt", "epoch000-step0000055.ckpt"]):
        (checkpoints / name).write_bytes(b"")
        os.utime(checkpoints / name, (1_000_000 + index, 1_000_000 + index))
    assert best_checkpoint(tmp_path) == checkpoints / "epoch000-step0000055.ckpt"
