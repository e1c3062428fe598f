"""The sweeps of Bi²Lane's Tables III-VII (sweeps/bi2lane_*.yaml): every job of each composes on the
tiny preset, passes the config checks, builds its net, and differs from the others in what the
table varies."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from lanelab.config_checks import register_schema
from lanelab.experiment.config import SCHEMA_NAME, TrainConfig, validate

SWEEPS = Path(__file__).resolve().parents[2] / "sweeps"
TABLES = {
    "bi2lane_modules": "+bi2lane_modules",  # III
    "bi2lane_feature_level": "model.net.aggregation",  # IV
    "bi2lane_direction": "model.net.direction",  # V
    "bi2lane_history_frames": "model.net.num_history_frames",  # VI
    "bi2lane_alignment": "model.net.temporal_alignment",  # VII
}


def swept_values(name: str) -> list[str]:
    (values,) = yaml.safe_load((SWEEPS / f"{name}.yaml").read_text())["hydra"]["sweeper"]["params"].values()
    return str(values).split(",")


@pytest.mark.parametrize("name", sorted(TABLES))
def test_every_job_of_each_table_builds_the_variant_it_names(name):
    register_schema(SCHEMA_NAME, TrainConfig)
    nets = []
    for value in swept_values(name):
        overrides = ["hydra.searchpath=[pkg://lanelab.conf]", "experiment=tiny", "paths.output_dir=unused"]
        with initialize_config_dir(config_dir=str(SWEEPS), version_base="1.3"):  # as lanelab-train --config-dir sweeps
            cfg = compose(name, overrides=[*overrides, f"{TABLES[name]}={value}"])
        validate(cfg)
        assert cfg.model.net._target_ == "lanelab.models.Bi2Lane"
        net = cfg.model.net
        nets.append((net.num_history_frames, net.direction, net.aggregation, net.temporal_alignment))
        instantiate(net)
        if name == "bi2lane_history_frames":
            assert cfg.data.num_frames == 6 and net.num_history_frames == int(value)
    assert len(set(nets)) == len(nets)  # each job a different model
    if name == "bi2lane_modules":
        assert nets[0] == (0, "forward", "none", True) and nets[1][2] == "none" and nets[2][2] == "bilevel"
