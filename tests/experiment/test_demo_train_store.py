"""``lanelab-demo demo.train_store=STORE`` trains on that store (one of auto-labels, say): no
training drive is synthesized or ingested, the held-out drives still are."""

from __future__ import annotations

from pathlib import Path

from lanelab import demo
from lanelab.experiment.config import load_train_config


def test_a_given_train_store_replaces_the_synthesized_training_drives(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(demo, "_tool", lambda name, *overrides: calls.append((name, overrides)))
    cfg = load_train_config(["experiment=demo", f"demo.out={tmp_path}", "demo.train_store=/data/autolabels",
                             "paths.output_dir=."])
    train_store, test_store = demo.prepare_stores(cfg.demo, tmp_path, 0.0)
    assert train_store == Path("/data/autolabels") and test_store == tmp_path / "clips_test"
    outputs = [o for _, overrides in calls for o in overrides if o.startswith(("output_dir=", "output="))]
    assert not any(o.endswith(("logs/train", "clips_train")) for o in outputs)
    assert f"output={tmp_path / 'clips_test'}" in outputs
