"""``lanelab-demo experiment=demo_long`` is the demo with five times the training drives and six
times the steps, the same models, held-out drives and comparison."""

from __future__ import annotations

from pathlib import Path

from lanelab import demo
from lanelab.experiment.config import load_train_config


def test_the_long_preset_renders_more_roads_and_trains_longer(tmp_path: Path, monkeypatch) -> None:
    short, long = (load_train_config([f"experiment={name}", "paths.output_dir=unused"]) for name in ("demo", "demo_long"))
    assert "num_logs=600" in long.demo.train_logs and "num_logs=120" in short.demo.train_logs
    assert long.trainer.max_steps == 6 * short.trainer.max_steps
    assert long.demo.test_logs == short.demo.test_logs and list(long.demo.models) == list(short.demo.models)

    trained = []

    def fake_train(cfg):
        trained.append(cfg.trainer.max_steps)
        Path(cfg.paths.output_dir, "checkpoints").mkdir(parents=True)
        Path(cfg.paths.output_dir, "checkpoints", "last.ckpt").touch()
        return {"train/steps": cfg.trainer.max_steps}

    monkeypatch.setattr(demo, "prepare_stores", lambda cfg, out, start: (tmp_path / "train", tmp_path / "test"))
    monkeypatch.setattr(demo, "train", fake_train)
    monkeypatch.setattr(demo, "evaluate_checkpoint", lambda *a, **k: {"overall": {"f1": 0.5}, "scenarios": []})
    demo.demo(["experiment=demo_long", f"demo.out={tmp_path}"])
    assert trained == [9000, 9000]
