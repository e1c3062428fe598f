"""A store's clips without ego motion: a temporal run refuses them in one line, or runs single-frame."""

from __future__ import annotations

from pathlib import Path

import pytest
from once_helpers import adapter_config, write_tiny_once

from data_ingest.once.adapter import adapt
from lanelab.config_checks import ConfigError
from lanelab.experiment.config import load_train_config
from lanelab.experiment.ego_motion import apply_ego_motion_policy, is_temporal


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("once")
    output = root / "store"
    adapt(adapter_config(write_tiny_once(root), output, poses=False))
    return output


def config(store: Path, tmp_path: Path, *overrides: str):
    return load_train_config([f"data.store={store}", f"paths.output_dir={tmp_path}", "logger=none", *overrides])


def test_a_temporal_model_refuses_clips_without_ego_motion(store: Path, tmp_path: Path) -> None:
    cfg = config(store, tmp_path)  # the window sampler, data.num_frames=4
    with pytest.raises(ConfigError) as refused:
        apply_ego_motion_policy(cfg, ["train", "val"])
    message = str(refused.value)
    assert "\n" not in message and f"data.store={store}" in message and "000027" in message
    assert "without_ego_motion=single_frame" in message and "poses=" in message


def test_streaming_is_temporal_too(store: Path, tmp_path: Path) -> None:
    cfg = config(store, tmp_path, "sampler=stream", "data.num_frames=1")
    assert is_temporal(cfg)
    with pytest.raises(ConfigError):
        apply_ego_motion_policy(cfg, ["test"])


def test_single_frame_runs_each_frame_alone(store: Path, tmp_path: Path) -> None:
    cfg = config(store, tmp_path, "sampler=stream", "without_ego_motion=single_frame")
    apply_ego_motion_policy(cfg, ["train", "val"])
    assert cfg.data.num_frames == 1 and cfg.sampler.train._target_.endswith("WindowSampler")
    assert not is_temporal(cfg)


def test_an_unknown_policy_is_a_bad_option(store: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="without_ego_motion='maybe'"):
        config(store, tmp_path, "without_ego_motion=maybe")
