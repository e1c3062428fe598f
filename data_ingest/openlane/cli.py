"""``lanelab-openlane``: OpenLane annotations + images -> one clip store, each segment a clip.

    lanelab-openlane annotations=DIR images=DIR output=STORE [scenario_lists=DIR] [scene_tags=FILE]

Options are Hydra overrides of ``conf/openlane.yaml``. Exits with status 1 when a segment
failed (the others are adapted all the same) and 2 on a bad option.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from data_ingest.adapter_cli import print_summary, run_or_exit
from data_ingest.openlane.config import SCHEMA_NAME, OpenLaneAdapterConfig, validate
from lanelab.config_checks import options_or_exit, register_schema, run_hydra_tool

register_schema(SCHEMA_NAME, OpenLaneAdapterConfig)


def run(cfg: OpenLaneAdapterConfig) -> bool:
    """Adapt and print a summary; True when every segment made it."""
    from data_ingest.openlane.adapter import adapt  # heavy imports only once the options are good

    results = adapt(cfg)
    done = print_summary(results, "segments", cfg.output)
    without_pose = [r.segment for r in done if not r.has_pose]
    if without_pose:
        print(f"note: {len(without_pose)} of {len(results)} segments have no pose in their files "
              "(OpenLane before v1.2): T_world_lane is the identity in their clips")
    return len(done) == len(results)


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="openlane")
def _run(cfg: DictConfig) -> None:
    run_or_exit("lanelab-openlane", run, options_or_exit("lanelab-openlane", cfg, OpenLaneAdapterConfig, validate))


def main() -> None:
    run_hydra_tool("lanelab-openlane", _run)


if __name__ == "__main__":
    main()
