"""``lanelab-ingest``: MCAP drive logs -> one clip store.

    lanelab-ingest input=PATH_OR_GLOB output=STORE_DIR [topics.image=... frames.world=... workers=N ...]
    lanelab-ingest output=STORE_DIR verify=true

Options are Hydra overrides of ``conf/ingest.yaml`` (unknown keys and wrong types are
named in one line, exit status 2). Exits with status 1 when a log failed (the others are ingested all the
same) or, with ``verify=true``, a clip file is missing or damaged; 2 when the options, the
input or the output cannot work (another run writing the store included); 130 on Ctrl-C,
with one line saying how many logs were recorded.
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig

from data_ingest.ingest.config import SCHEMA_NAME, IngestConfig, validate
from lanelab.config_checks import BAD_OPTION_STATUS, ConfigError, bad_options_exit, register_schema, run_hydra_tool, typed

register_schema(SCHEMA_NAME, IngestConfig)


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="ingest")
def _run(cfg: DictConfig) -> None:
    from data_ingest.ingest.ingest import FAILED, ingest, verify  # heavy imports only once the options are good

    with bad_options_exit("lanelab-ingest"):
        options = validate(typed(cfg, IngestConfig))
    try:
        if options.verify:
            sys.exit(1 if verify(options.output) else 0)
        results = ingest(options)
    except ConfigError as err:  # no log there, or an output that cannot take them
        print(f"lanelab-ingest: {err}", file=sys.stderr)
        sys.exit(BAD_OPTION_STATUS)
    except KeyboardInterrupt as err:  # IngestInterrupted says what was recorded
        print(f"lanelab-ingest: {str(err) or 'interrupted before any log was recorded'}", file=sys.stderr)
        sys.exit(130)
    if any(result.status == FAILED for result in results):
        sys.exit(1)


def main() -> None:
    run_hydra_tool("lanelab-ingest", _run)


if __name__ == "__main__":
    main()
