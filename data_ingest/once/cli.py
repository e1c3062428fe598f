"""``lanelab-once``: ONCE-3DLanes labels + images -> one clip store, each sequence a clip.

    lanelab-once root=DIR output=STORE [images=DIR] [poses=DIR] [splits.test=test]

Options are Hydra overrides of ``conf/once.yaml``. Exits with status 1 when a sequence failed
(the others are adapted all the same) and 2 on a bad option.
"""

from __future__ import annotations

import sys
from collections import Counter

import hydra
from omegaconf import DictConfig

from data_ingest.once.config import SCHEMA_NAME, OnceAdapterConfig, validate
from lanelab.config_checks import options_or_exit, register_schema, run_hydra_tool
from lanelab.json_files import LaneFileError
from lanelab.store import ManifestError

register_schema(SCHEMA_NAME, OnceAdapterConfig)


def run(cfg: OnceAdapterConfig) -> bool:
    """Adapt and print a summary; True when every sequence made it."""
    from data_ingest.once.adapter import FAILED, adapt  # heavy imports only once the options are good

    results = adapt(cfg)
    for result in results:
        if result.status == FAILED:
            print(f"failed: {result.sequence}: {result.error}")
    done = [r for r in results if r.status != FAILED]
    statuses = Counter(result.status for result in results)
    print(f"{len(results)} sequences: " + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items()))
          + f"; {sum(r.num_frames for r in done)} frames in {cfg.output}")
    empty = sum(r.empty for r in done)
    if empty:
        print(f"note: {empty} empty label files skipped (as LATR's loader skips them)")
    without_pose = [r.sequence for r in done if not r.has_pose]
    if without_pose:
        print(f"note: {len(without_pose)} of {len(results)} sequences have no ego poses "
              f"({'no poses=' if cfg.poses is None else 'no annotation file under poses='}): T_world_lane is the identity in their clips, "
              "listed as clips_without_pose; temporal models refuse them unless run with without_ego_motion=single_frame")
    return statuses[FAILED] == 0


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="once")
def _run(cfg: DictConfig) -> None:
    options = options_or_exit("lanelab-once", cfg, OnceAdapterConfig, validate)
    try:  # a ConfigError of run ends as a bad option (run_hydra_tool)
        ok = run(options)
    except (LaneFileError, ManifestError) as err:
        print(f"lanelab-once: {err}", file=sys.stderr)
        sys.exit(1)
    if not ok:
        sys.exit(1)


def main() -> None:
    run_hydra_tool("lanelab-once", _run)


if __name__ == "__main__":
    main()
