"""``lanelab-predict``: a trained model over MCAP drive logs -> Foxglove-viewable MCAP logs.

    lanelab-predict checkpoint=FILE input=LOG_OR_GLOB output=DIR [merge=true] [accelerator=cpu|gpu|auto]
                    [topics.image=... frames.world=... clips.gap_s=... predictions.lanes=... preview_frames=N]

Options are Hydra overrides of ``conf/predict.yaml``. Writes ``<output>/<log name>.mcap`` per
log (:mod:`log_predict.predict`) and ``<output>/<log name>.png``. Exits with status 1 when a
log could not be predicted (the others are, all the same) or the checkpoint cannot be used
(unreadable, not lanelab-train's, NaN or inf weights), each said in one line naming the file;
2 on a bad option; 130 on Ctrl-C (no half-written file is left).
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig

from lanelab.config_checks import ConfigError, options_or_exit, register_schema, run_hydra_tool
from log_predict.config import SCHEMA_NAME, PredictConfig, validate

register_schema(SCHEMA_NAME, PredictConfig)
NAME = "lanelab-predict"


def run(cfg: PredictConfig) -> int:
    """Predict the logs of validated options; the exit status."""
    # Heavy imports (torch, the model) only once the options are good.
    from data_ingest.ingest.errors import LogError
    from lanelab.deploy.trained import load_trained
    from lanelab.finite import NonFiniteError
    from log_predict.predict import predict

    try:
        detector = load_trained(cfg.checkpoint, cfg.accelerator)
        results = predict(cfg, detector)
    except (ConfigError, NonFiniteError, LogError) as err:
        print(f"{NAME}: {err}", file=sys.stderr)
        return 1
    return 1 if any(result.error is not None for result in results) else 0


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="predict")
def _run(cfg: DictConfig) -> None:
    options = options_or_exit(NAME, cfg, PredictConfig, validate)
    try:
        status = run(options)
    except KeyboardInterrupt:
        print(f"{NAME}: interrupted; the logs predicted before are written, the one in progress is not",
              file=sys.stderr)
        sys.exit(130)
    sys.exit(status)


def main() -> None:
    run_hydra_tool(NAME, _run)


if __name__ == "__main__":
    main()
