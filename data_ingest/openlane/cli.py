"""``lanelab-openlane``: OpenLane annotations + images -> one clip store, each segment a clip.

    lanelab-openlane annotations=DIR images=DIR output=STORE [scenario_lists=DIR] [scene_tags=FILE]

Options are Hydra overrides of ``conf/openlane.yaml``. Exits with status 1 when a segment
failed (the others are adapted all the same) and 2 on a bad option.
"""

from __future__ import annotations

import sys
from collections import Counter

import hydra
from omegaconf import DictConfig

from data_ingest.openlane.config import SCHEMA_NAME, OpenLaneAdapterConfig, validate
from lanelab.config_checks import options_or_exit, register_schema, run_hydra_tool
from lanelab.json_files import LaneFileError
from lanelab.store import ManifestError

register_schema(SCHEMA_NAME, OpenLaneAdapterConfig)


def run(cfg: OpenLaneAdapterConfig) -> bool:
    """Adapt and print a summary; True when every segment made it."""
    from data_ingest.openlane.adapter import FAILED, adapt  # heavy imports only once the options are good

    results = adapt(cfg)
    for result in results:
        if result.status == FAILED:
            print(f"failed: {result.segment}: {result.error}")
    statuses = Counter(result.status for result in results)
    without_pose = [r.segment for r in results if r.status != FAILED and not r.has_pose]
    print(f"{len(results)} segments: " + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items()))
          + f"; {sum(r.num_frames for r in results if r.status != FAILED)} frames in {cfg.output}")
    if without_pose:
        print(f"note: {len(without_pose)} of {len(results)} segments have no pose in their files "
              "(OpenLane before v1.2): T_world_lane is the identity in their clips")
    return statuses[FAILED] == 0


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="openlane")
def _run(cfg: DictConfig) -> None:
    options = options_or_exit("lanelab-openlane", cfg, OpenLaneAdapterConfig, validate)
    try:  # a ConfigError of run ends as a bad option (run_hydra_tool)
        ok = run(options)
    except (LaneFileError, ManifestError) as err:
        print(f"lanelab-openlane: {err}", file=sys.stderr)
        sys.exit(1)
    if not ok:
        sys.exit(1)


def main() -> None:
    run_hydra_tool("lanelab-openlane", _run)


if __name__ == "__main__":
    main()
