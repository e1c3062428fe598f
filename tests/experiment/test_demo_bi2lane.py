"""``lanelab-demo experiment=demo_bi2lane`` runs the demo's recipe for Bi²Lane and its
single-frame baseline: those two models are trained (tiny sizes, the demo's data) and compared."""

from __future__ import annotations

from pathlib import Path

from lanelab import demo


def test_the_bi2lane_preset_trains_and_compares_bi2lane_and_its_baseline(tmp_path: Path, monkeypatch) -> None:
    trained = {}

    def fake_train(cfg):
        trained[cfg.model.net._target_, cfg.model.net.num_history_frames] = cfg
        Path(cfg.paths.output_dir, "checkpoints").mkdir(parents=True)
        Path(cfg.paths.output_dir, "checkpoints", "last.ckpt").touch()
        return {"train/steps": cfg.trainer.max_steps}

    def fake_report(checkpoint, store, out, **options):
        return {"overall": {"f1": 0.5, "x_error_close": 0.3}, "scenarios": []}

    monkeypatch.setattr(demo, "prepare_stores", lambda cfg, out, start: (tmp_path / "train", tmp_path / "test"))
    monkeypatch.setattr(demo, "train", fake_train)
    monkeypatch.setattr(demo, "evaluate_checkpoint", fake_report)
    demo.demo(["experiment=demo_bi2lane", f"demo.out={tmp_path}"])

    assert set(trained) == {("lanelab.models.bi2lane.Bi2Lane", 3), ("lanelab.models.bi2lane.Bi2Lane", 0)}
    for cfg in trained.values():  # the demo's recipe and data, Bi²Lane's tiny size
        assert list(cfg.data.image_size) == [96, 128] and cfg.trainer.max_steps == 1500
        assert cfg.model.net.embed_dim == 32 and cfg.data.store == str(tmp_path / "train")
    table = (tmp_path / demo.COMPARISON_MD).read_text()
    assert "| bi2lane |" in table and "| bi2lane_baseline |" in table and "sparselanestp" not in table
