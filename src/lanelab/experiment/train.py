"""``lanelab-train``: compose an experiment from ``conf/`` and run it.

    lanelab-train [experiment=NAME] [model=...] [sampler=...] [trainer=...] [logger=...] [key=value ...]
    lanelab-train --multirun sweep=memory_length experiment=tiny

Builds the run from the config (:func:`lanelab.experiment.build.build_run`: the datamodule,
the LightningModule, the callbacks, the loggers and the Trainer), then fits, tests and
evaluates as ``train``, ``test`` and ``evaluation.enabled`` say. The run folder holds the
config (``.hydra/``), the checkpoints, the logs, ``metrics.json`` (the last value of every
logged metric, what ``lanelab-sweep-report`` reads; with the evaluation, also the blind
prior's scores on the evaluated split as ``blind_prior/<metric>``) and the evaluation report.
Exits with status 2 on a bad option, naming the key, and with status 1 when NaN or inf stop the
run (:class:`~lanelab.finite.NonFiniteError`: a store's frame, naming the clip and frame; a loss,
naming the step and the batch's frames; a checkpoint's weights, naming the file).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Mapping
from pathlib import Path

import hydra
import torch
from lightning.pytorch.loggers import WandbLogger
from omegaconf import DictConfig

from lanelab.atomic_file import atomic_output
from lanelab.config_checks import ConfigError, register_schema
from lanelab.experiment import BLIND_PRIOR_PREFIX, METRICS_JSON
from lanelab.experiment.build import build_run
from lanelab.experiment.config import SCHEMA_NAME, TrainConfig, validate
from lanelab.finite import NonFiniteError
from lanelab.store import ClipFileError, ManifestError

register_schema(SCHEMA_NAME, TrainConfig)


def train(cfg: DictConfig) -> dict[str, float]:
    """Run a composed, validated config; the last value of every metric logged by fitting
and testing (also written to ``metrics.json``)."""
    run = build_run(cfg)
    trainer, module, datamodule = run.trainer, run.module, run.datamodule
    weights = cfg.ckpt_path
    metrics: dict[str, float] = {}
    if cfg.train:
        trainer.fit(module, datamodule=datamodule, ckpt_path=cfg.ckpt_path)
        metrics.update(_floats(trainer.callback_metrics), **{"train/steps": float(trainer.global_step)})
        # Test and evaluate the best checkpoint; without one (fast_dev_run), the weights in memory.
        weights = getattr(trainer.checkpoint_callback, "best_model_path", None) or None
    if cfg.test:
        trainer.test(module, datamodule=datamodule, ckpt_path=weights)
        metrics.update(_floats(trainer.callback_metrics))
    if cfg.evaluation.enabled:
        from lanelab.experiment.evaluate import evaluate  # the report's imports only when asked for

        report = evaluate(trainer, module, datamodule, weights, cfg.evaluation)
        if metrics and report is not None and report.reference is not None and report.reference.overall is not None:
            # The blind prior's scores on the evaluated split, the reference row of lanelab-sweep-report.
            metrics.update({f"{BLIND_PRIOR_PREFIX}{key}": float(value) for key, value in report.reference.overall.items()})

    for logger in run.loggers:
        if isinstance(logger, WandbLogger):
            logger.experiment.finish()  # else the next run in this process (a sweep job) would reuse it
    if trainer.is_global_zero and metrics:  # an evaluation alone logs none
        _write_metrics(Path(cfg.paths.output_dir) / METRICS_JSON, metrics)
    return metrics


def _floats(metrics: Mapping[str, torch.Tensor]) -> dict[str, float]:
    return {key: float(value) for key, value in metrics.items()}


def _write_metrics(path: Path, metrics: dict[str, float]) -> None:
    """Metrics as JSON; a value no frame had (NaN) as null."""
    values = {key: None if math.isnan(value) else value for key, value in metrics.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(values, indent=1, sort_keys=True) + "\n")


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="train")
def _run(cfg: DictConfig) -> float | None:
    try:
        validate(cfg)
    except ConfigError as err:
        print(f"lanelab-train: bad option: {err}", file=sys.stderr)
        sys.exit(2)
    try:
        metrics = train(cfg)
    except (NonFiniteError, ManifestError, ClipFileError) as err:  # bad numbers, a missing or damaged store
        print(f"lanelab-train: {err}", file=sys.stderr)
        sys.exit(1)
    # The value a Hydra sweeper (e.g. optuna) optimises.
    return metrics.get("val/f1")


def main() -> None:
    _run()


if __name__ == "__main__":
    main()
