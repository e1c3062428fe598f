"""lanelab-demo end to end at a miniature scale: synthesize, ingest, train both models,
evaluate them on held-out drives, print and write the comparison."""

from pathlib import Path

import pytest

from lanelab.demo import COMPARISON_MD, main

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
    for model in ("sparselanestp", "latr_baseline"):
        assert (tmp_path / model / "heldout" / "pictures.png").is_file()
    assert "report and pictures in" in capsys.readouterr().out
