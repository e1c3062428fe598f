"""lanelab-demo end to end at a miniature scale: synthesize, ingest, train both models,
evaluate them on held-out drives, print and write the comparison."""

import os
from pathlib import Path

import pytest
from omegaconf import DictConfig, OmegaConf

import lanelab.demo as demo_module
from lanelab.demo import COMPARISON_MD, best_checkpoint, main, same_steps, short_training_note

MINIATURE = [
    "demo.synth=['camera.width=96','camera.height=64','fps=5','workers=1']",
    "demo.train_logs=['num_logs=2','duration_s=2','seed=1']",
    "demo.test_logs.fog=['num_logs=1','duration_s=1','seed=101','world.weather=fog']",
    "demo.test_logs.traffic=['num_logs=1','duration_s=1','seed=102']",
    "demo.ingest_train=['split.by=clip','split.train=0.5','split.val=0.5','split.test=0.0','clips.max_length_s=0.4']",
    "data.image_size=[64,96]", "trainer.max_steps=2", "trainer.limit_val_batches=1", "evaluation.num_pictures=1",
]  # fmt: skip


@pytest.mark.slow
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


HELDOUT_REPORT = {"overall": {"f1": 0.4, "x_error_near": 0.2, "z_error_near": 0.1}, "scenarios": []}


def run_demo_with_fake_training(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, slow: str | None) -> dict[str, int]:
    """lanelab-demo's loop with training replaced: every model runs trainer.max_steps, except
    ``slow``, which the demo's wall-clock cap stops at step 827 (a busy machine); evaluation and
    the stores are stand-ins. The steps each model trained."""
    trained: dict[str, int] = {}

    def train(cfg: DictConfig) -> dict[str, float]:
        model = Path(cfg.paths.output_dir).parent.name
        capped = model == slow and cfg.trainer.max_time is not None
        trained[model] = min(827, cfg.trainer.max_steps) if capped else cfg.trainer.max_steps
        return {"train/steps": float(trained[model])}

    monkeypatch.setattr(demo_module, "prepare_stores", lambda *_: (tmp_path / "clips_train", tmp_path / "clips_test"))
    monkeypatch.setattr(demo_module, "train", train)
    monkeypatch.setattr(demo_module, "evaluate_checkpoint", lambda *_, **__: HELDOUT_REPORT)
    demo_module.demo([f"demo.out={tmp_path}"])
    return trained


def test_a_wall_clock_cap_stops_every_model_at_the_same_step_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 38: trainer.max_time stopped SparseLaneSTP at 827 of 1,500 steps while the baseline
    ran all 1,500; now the baseline trains the same 827, and a line above the table says so."""
    assert run_demo_with_fake_training(tmp_path, monkeypatch, slow="sparselanestp") == {
        "sparselanestp": 827, "latr_baseline": 827}  # fmt: skip
    table = (tmp_path / COMPARISON_MD).read_text()
    assert "| sparselanestp | 827 |" in table and "| latr_baseline | 827 |" in table
    note = "Note: training stopped before trainer.max_steps=1500"
    assert note in table and table.index(note) < table.index("| model |")
    assert "sparselanestp at step 827, latr_baseline at step 827; every model trained the same 827 steps" in table
    assert note in capsys.readouterr().out


def test_without_a_cap_hit_every_model_trains_all_its_steps_and_no_note(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    trained = run_demo_with_fake_training(tmp_path, monkeypatch, slow=None)
    assert trained == {"sparselanestp": 1500, "latr_baseline": 1500}
    assert "Note:" not in (tmp_path / COMPARISON_MD).read_text()


def test_models_stopped_at_different_steps_are_said_not_to_compare() -> None:
    trainer = OmegaConf.create({"max_steps": 1500, "max_time": "00:00:07:00", "max_epochs": 100})
    note = short_training_note({"bi2lane": 1500, "bi2lane_baseline": 600}, trainer)
    assert "bi2lane_baseline at step 600;" in note and "so the rows do not compare alike" in note
    assert same_steps({}) == []  # the first model trains as configured
    assert same_steps({"bi2lane": 600, "x": 1}) == ["trainer.max_steps=600", "trainer.max_time=null"]
