"""ONCE-3DLanes in and out: release layout -> store -> ONCE files equal to the source labels, and
the ground truth scored as predictions gives F1 1 (the built-in metric and lanelab-eval format=once)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from once_helpers import CALIBRATION, SEQUENCES, WITH_POSES, adapt_tiny_once, adapter_config, write_tiny_once

from data_ingest.once.adapter import adapt
from lanelab.metrics.once import best, evaluate_once
from lanelab.once.camera import fixed_T_lane_cam
from lanelab.once.write import export_ground_truth, write_prediction
from lanelab.store import WITHOUT_POSE, ClipStore, read_manifest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return write_tiny_once(tmp_path_factory.mktemp("once"))


@pytest.fixture(scope="module")
def store(tiny, tmp_path_factory) -> Path:
    return adapt_tiny_once(tiny, tmp_path_factory.mktemp("store") / "store")


def latr_extrinsic() -> np.ndarray:
    """LATR's ONCE camera as its loader builds it (JMoonr/LATR data/Load_Data.py), for comparison."""
    p, h = 0.3 / 180 * np.pi, 1.5
    E = np.array([[np.cos(p), 0, -np.sin(p), 0], [0, 1, 0, 0], [np.sin(p), 0, np.cos(p), h], [0, 0, 0, 1]])
    R_vg = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]])
    R_gc = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0.0]])
    E[:3, :3] = np.linalg.inv(R_vg) @ E[:3, :3] @ R_vg @ R_gc
    return E


def test_the_store_follows_the_contract(store: Path) -> None:
    manifest = read_manifest(store)
    assert {(c.clip_id, c.split) for c in manifest.clips} == {
        (sequence, split) for split, sequences in SEQUENCES.items() for sequence in sequences}
    assert manifest.options["made_by"] == "lanelab-once"
    assert manifest.options[WITHOUT_POSE] == sorted(s for seqs in SEQUENCES.values() for s in seqs if s != WITH_POSES)
    clips = ClipStore(store)
    np.testing.assert_allclose(fixed_T_lane_cam(1.5, 0.3), latr_extrinsic(), atol=1e-15)
    for split, sequences in SEQUENCES.items():
        for sequence, stamps in sequences.items():
            frames = clips.read_frames(sequence)
            assert [f.timestamp_ns for f in frames] == [s * 1_000_000 for s in stamps]
            for frame in frames:
                np.testing.assert_array_equal(frame.K, np.array(CALIBRATION)[:, :3])
                np.testing.assert_allclose(frame.T_lane_cam, latr_extrinsic(), atol=1e-15)
                assert frame.image_encoding == "jpeg" and (frame.width, frame.height) == (16, 8)
                for lane in frame.lanes:
                    assert lane.category == 0 and (np.diff(lane.points[:, 1]) > 0).all()
            if sequence == WITH_POSES:  # the camera (at the LiDAR here) where the poses put it
                for k, frame in enumerate(frames):
                    np.testing.assert_allclose((frame.T_world_lane @ frame.T_lane_cam)[:3, 3], [5.0 * k, 0.2 * k, 0],
                                               atol=1e-12)
            else:
                assert all((f.T_world_lane == np.eye(4)).all() for f in frames)


def test_ground_truth_written_back_equals_the_source_labels(tiny, store: Path, tmp_path: Path) -> None:
    for split in SEQUENCES:
        written = export_ground_truth(store, split, tmp_path / split)
        assert len(written) == sum(len(stamps) for stamps in SEQUENCES[split].values())
        for path in written:
            source = tiny.labels[f"{split}/{path.relative_to(tmp_path / split).as_posix()}"]
            content = json.loads(path.read_text())
            assert content["calibration"] == source["calibration"]
            assert len(content["lanes"]) == len(source["lanes"])
            for lane, source_lane in zip(content["lanes"], source["lanes"]):
                np.testing.assert_allclose(lane, source_lane, atol=2e-5)  # float32 in the store


def test_ground_truth_as_predictions_scores_f1_one(tiny, store: Path, tmp_path: Path) -> None:
    clips = ClipStore(store)
    for clip in clips.clips_in("val"):
        for frame in clips.read_frames(clip.clip_id):
            write_prediction(tmp_path / "pred", clip.clip_id, frame, frame.lanes)
    top = best(evaluate_once(tiny.root / "val", tmp_path / "pred"))
    assert (top["f1"], top["precision"], top["recall"]) == (1.0, 1.0, 1.0)
    assert top["gt_lanes"] == 9 and top["cd"] < 1e-4

    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    result = subprocess.run([sys.executable, "-m", "lanelab.experiment.eval_cli", "format=once",
                             f"gt={tiny.root / 'val'}", f"pred={tmp_path / 'pred'}", f"out={tmp_path / 'eval'}"],
                            capture_output=True, text=True, env=env, timeout=120, check=False)  # fmt: skip
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "eval" / "report.json").read_text())
    assert report["best"]["f1"] == 1.0 and len(report["thresholds"]) == 18
    assert "**0.10**" in (tmp_path / "eval" / "report.md").read_text()


def test_re_running_keeps_every_clip(tiny, store: Path) -> None:
    results = adapt(adapter_config(tiny, store))
    assert [r.status for r in results] == ["kept"] * 3
