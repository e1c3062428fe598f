"""``lanelab-once``: ONCE-3DLanes labels + images -> one clip store, each sequence a clip.

    lanelab-once root=DIR output=STORE [images=DIR] [poses=DIR] [splits.test=test]

Options are Hydra overrides of ``conf/once.yaml``. Exits with status 1 when a sequence failed
(the others are adapted all the same) and 2 on a bad option.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from data_ingest.adapter_cli import print_summary, run_or_exit
from data_ingest.once.config import SCHEMA_NAME, OnceAdapterConfig, validate
from lanelab.config_checks import options_or_exit, register_schema, run_hydra_tool

register_schema(SCHEMA_NAME, OnceAdapterConfig)


def run(cfg: OnceAdapterConfig) -> bool:
    """Adapt and print a summary; True when every sequence made it."""
    from data_ingest.once.adapter import adapt  # heavy imports only once the options are good

    results = adapt(cfg)
    done = print_summary(results, "sequences", cfg.output)
    empty = sum(r.empty for r in done)
    if empty:
        print(f"note: {empty} empty label files skipped (as LATR's loader skips them)")
    without_pose = [r.sequence for r in done if not r.has_pose]
    if without_pose:
        print(f"note: {len(without_pose)} of {len(results)} sequences have no ego poses "
              f"({'no poses=' if cfg.poses is None else 'no annotation file under poses='}): T_world_lane is the identity in their clips, "
              "listed as clips_without_pose; temporal models refuse them unless run with without_ego_motion=single_frame")
    return len(done) == len(results)


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="once")
def _run(cfg: DictConfig) -> None:
    run_or_exit("lanelab-once", run, options_or_exit("lanelab-once", cfg, OnceAdapterConfig, validate))


def main() -> None:
    run_hydra_tool("lanelab-once", _run)


if __name__ == "__main__":
    main()
