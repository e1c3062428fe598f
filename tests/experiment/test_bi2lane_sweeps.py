"""The sweeps of Bi²Lane's Tables III-VII (conf/sweep/bi2lane_*.yaml): every job of each composes on the
tiny preset, passes the config checks, builds its net, and differs from the others in what the
table varies."""

from __future__ import annotations

from importlib.resources import files

import pytest
import yaml
from hydra.utils import instantiate

from lanelab.experiment.config import load_train_config

SWEEPS = files("lanelab.conf") / "sweep"
TABLES = {
    "bi2lane_modules": "+sweep/bi2lane_modules",  # III
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
    nets = []
    for value in swept_values(name):
        cfg = load_train_config([f"sweep={name}", "experiment=tiny", "paths.output_dir=unused", f"{TABLES[name]}={value}"])
        assert cfg.model.net._target_ == "lanelab.models.bi2lane.Bi2Lane"
        net = cfg.model.net
        nets.append((net.num_history_frames, net.direction, net.aggregation, net.temporal_alignment))
        instantiate(net)
        if name == "bi2lane_history_frames":
            assert cfg.data.num_frames == 6 and net.num_history_frames == int(value)
    assert len(set(nets)) == len(nets)  # each job a different model
    if name == "bi2lane_modules":
        assert nets[0] == (0, "forward", "none", True) and nets[1][2] == "none" and nets[2][2] == "bilevel"
