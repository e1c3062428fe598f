"""``lanelab-synth``: write synthetic drive logs (MCAP) and, on request, a preview picture.

    lanelab-synth output_dir=DIR num_logs=N duration_s=S seed=K encoding=ros2|foxglove [--preview]

Options are Hydra overrides of ``conf/synth.yaml``; ``--preview`` is short for
``preview=true``. Logs already present are kept (an interrupted run resumes) unless
``overwrite=true``. A bad option is named in one line before anything is written (exit status 2),
as is an output folder that another run is writing or that cannot be written.
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig

from data_ingest.synth.config import SCHEMA_NAME, SynthConfig, validate
from lanelab.config_checks import (
    BAD_OPTION_STATUS,
    ConfigError,
    bad_options_exit,
    register_schema,
    run_hydra_tool,
    typed,
)

register_schema(SCHEMA_NAME, SynthConfig)


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="synth")
def _run(cfg: DictConfig) -> None:
    with bad_options_exit("lanelab-synth"):
        synth_cfg = validate(typed(cfg, SynthConfig))
    from data_ingest.synth.synthesize import synthesize  # heavy imports only once the options are good

    try:
        synthesize(synth_cfg)
    except ConfigError as err:  # the folder is another run's, or cannot be written
        print(f"lanelab-synth: {err}", file=sys.stderr)
        sys.exit(BAD_OPTION_STATUS)


def main() -> None:
    sys.argv = [("preview=true" if arg == "--preview" else arg) for arg in sys.argv]
    run_hydra_tool("lanelab-synth", _run)


if __name__ == "__main__":
    main()
