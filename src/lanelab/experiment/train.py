"""``lanelab-train``: compose an experiment from ``conf/`` and run it.

    lanelab-train [experiment=NAME] [model=...] [sampler=...] [trainer=...] [logger=...] [key=value ...]
    lanelab-train --multirun sweep=memory_length experiment=tiny

Builds the run from the config (:func:`lanelab.experiment.build.build_run`: the datamodule,
the LightningModule, the callbacks, the loggers and the Trainer), then fits, tests and
evaluates as ``train``, ``test`` and ``evaluation.enabled`` say. The run folder holds the
config (``.hydra/``), the checkpoints, the logs, ``metrics.json`` (the last value of every
logged metric, what ``lanelab-sweep-report`` reads; with the evaluation, also the blind
prior's scores on the evaluated split as ``blind_prior/<metric>``) and the evaluation report.
The console shows the run folder first, Rich's progress bar with the loss and validation F1,
and a closing table (best checkpoint, best validation F1, test F1, steps, time); the same lines
(and the warnings) go to ``<run>/train.log``.

Exits with status 2 on a bad option, naming the key, and on a store that cannot feed the run
(none there, an unreadable manifest, a split without clips, windows its clips cannot give),
checked before the model is built; also on a ``ckpt_path`` that cannot serve the run (unreadable,
no Lightning checkpoint, another model's weights, past ``max_epochs``:
:mod:`lanelab.experiment.checkpoints`) and on a run folder in use by another lanelab-train or
that cannot be written (:mod:`lanelab.experiment.run_folder`). With status 1 on a damaged or
missing clip file and when NaN or inf stop the run (:class:`~lanelab.finite.NonFiniteError`: a
store's frame, naming the clip and frame; a loss, naming the step and the batch's frames; a
checkpoint's weights, naming the file). SIGTERM (a scheduler's stop) ends the run at the end of
the step, with ``last.ckpt`` saved, one line saying where and how to resume, and status 143, as
a process the signal ends: a scheduler must not count the run as finished.
"""

from __future__ import annotations

import json
import logging
import math
import signal
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import hydra
import lightning.pytorch as pl
import torch
from lightning.pytorch.loggers import WandbLogger
from lightning.pytorch.utilities.exceptions import SIGTERMException
from omegaconf import DictConfig

from lanelab.atomic_file import atomic_output
from lanelab.config_checks import BAD_OPTION_STATUS, bad_options_exit, register_schema, run_hydra_tool
from lanelab.experiment import BLIND_PRIOR_PREFIX, METRICS_JSON
from lanelab.experiment.build import Run, build_run
from lanelab.experiment.checkpoints import check_resume
from lanelab.experiment.config import SCHEMA_NAME, TrainConfig, validate
from lanelab.finite import NonFiniteError
from lanelab.lightning.console import ignore_known_warnings, route_lightning_logs
from lanelab.data.worker_errors import error_message
from lanelab.store import ClipFileError, DataError, ManifestError

register_schema(SCHEMA_NAME, TrainConfig)
log = logging.getLogger("lanelab.train")
SIGTERM_STATUS = 128 + signal.SIGTERM  # 143, as a shell reports a process the signal ended


class RunStopped(Exception):
    """SIGTERM stopped the run; the message says at which step, where its state is and how to resume."""


def train(cfg: DictConfig) -> dict[str, float]:
    """Run a composed, validated config; the last value of every metric logged by fitting
and testing (also written to ``metrics.json``)."""
    start = time.monotonic()
    log.info("lanelab-train: run folder %s", cfg.paths.output_dir)
    # Before the loggers start: W&B looks for the code's git repository from it.
    Path(cfg.paths.output_dir).mkdir(parents=True, exist_ok=True)
    run = build_run(cfg)
    trainer, module, datamodule = run.trainer, run.module, run.datamodule
    if cfg.ckpt_path is not None:
        check_resume(trainer, module, cfg.ckpt_path, fitting=cfg.train)
    with _stopped_by_sigterm(cfg, trainer):
        metrics = _fit_test_evaluate(cfg, run)
    if trainer.is_global_zero and metrics:  # an evaluation alone logs none
        _write_metrics(Path(cfg.paths.output_dir) / METRICS_JSON, metrics)
    if trainer.is_global_zero:
        log.info("%s", closing_table(cfg, trainer, metrics, time.monotonic() - start))
    return metrics


def _fit_test_evaluate(cfg: DictConfig, run: Run) -> dict[str, float]:
    """What the config asks of the built run; the last value of every metric logged."""
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
        from lanelab.experiment.evaluate import evaluate, log_evaluation  # the report's imports only when asked for

        report = evaluate(trainer, module, datamodule, weights, cfg.evaluation)
        if report is not None:
            log_evaluation(run.loggers, report, Path(cfg.evaluation.out), trainer.global_step)
        if metrics and report is not None and report.reference is not None and report.reference.overall is not None:
            # The blind prior's scores on the evaluated split, the reference row of lanelab-sweep-report.
            metrics.update({f"{BLIND_PRIOR_PREFIX}{key}": float(value) for key, value in report.reference.overall.items()})

    for logger in run.loggers:
        if isinstance(logger, WandbLogger):
            logger.experiment.finish()  # else the next run in this process (a sweep job) would reuse it
    return metrics


@contextmanager
def _stopped_by_sigterm(cfg: DictConfig, trainer: pl.Trainer) -> Iterator[None]:
    """Lightning ends a run on SIGTERM after the step with a SystemExit of status 0, which a
    scheduler would count as finished; :class:`RunStopped` instead, naming the saved state."""
    try:
        yield
    except SIGTERMException:
        last = getattr(trainer.checkpoint_callback, "last_model_path", "") or None
        saved = f"the state is saved in {last}" if last else "no checkpoint was saved"
        raise RunStopped(f"stopped by SIGTERM at step {trainer.global_step} (epoch {trainer.current_epoch}); {saved}; "
                         f"resume with the same command and hydra.run.dir={cfg.paths.output_dir} ckpt_path=last") from None


def closing_table(cfg: DictConfig, trainer: pl.Trainer, metrics: Mapping[str, float], seconds: float) -> str:
    """What a run leaves: its folder, best checkpoint, best validation F1, test F1, steps and time."""
    best = getattr(trainer.checkpoint_callback, "best_model_path", "") or None
    rows = [("run folder", str(cfg.paths.output_dir))]
    if cfg.train:
        rows += [("best checkpoint", best or _no_checkpoint(trainer)),
                 ("best val F1", _percent(metrics.get("val/f1_best"))),
                 ("steps", f"{trainer.global_step} ({trainer.current_epoch} epochs)")]  # fmt: skip
    rows.append(("test F1", _percent(metrics.get("test/f1")) if cfg.test else "not tested (test=true tests the best checkpoint)"))
    if cfg.evaluation.enabled:
        rows.append(("evaluation", str(Path(cfg.evaluation.out) / "report.md")))
    rows.append(("time", _duration(seconds)))
    width = max(len(name) for name, _ in rows)
    return "\n".join(["", "lanelab-train: done", *(f"  {name:<{width}}  {value}" for name, value in rows)])


def _no_checkpoint(trainer: pl.Trainer) -> str:
    if trainer.fast_dev_run:
        return "none (fast_dev_run writes none)"
    if trainer.checkpoint_callback is None:
        return "none (no checkpoint callback)"
    return "none (no validation ran: validate within an epoch with trainer.val_check_interval=STEPS)"


def _percent(value: float | None) -> str:
    return "–" if value is None or math.isnan(value) else f"{100 * value:.1f} %"


def _duration(seconds: float) -> str:
    minutes, seconds = divmod(seconds, 60)
    return f"{int(minutes)} min {seconds:.1f} s" if minutes else f"{seconds:.1f} s"


def _floats(metrics: Mapping[str, torch.Tensor]) -> dict[str, float]:
    return {key: float(value) for key, value in metrics.items()}


def _write_metrics(path: Path, metrics: dict[str, float]) -> None:
    """Metrics as JSON; a value no frame had (NaN) as null."""
    values = {key: None if math.isnan(value) else value for key, value in metrics.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(values, indent=1, sort_keys=True) + "\n")


@contextmanager
def run_errors_exit(tool: str) -> Iterator[None]:
    """What stops a run, as one line on stderr and the documented exit status: 2 for a bad option
    or a store that cannot feed the run, 1 for a damaged or missing clip file or NaN / inf, 143
    for SIGTERM."""
    try:
        with bad_options_exit(tool):
            yield
    except (ManifestError, DataError) as err:  # checked before anything is built
        print(f"{tool}: {err}", file=sys.stderr)
        sys.exit(BAD_OPTION_STATUS)
    except (NonFiniteError, ClipFileError) as err:  # also from a loader worker, while training
        print(f"{tool}: {error_message(err)}", file=sys.stderr)
        sys.exit(1)
    except RunStopped as err:
        print(f"{tool}: {err}", file=sys.stderr)
        sys.exit(SIGTERM_STATUS)


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="train")
def _run(cfg: DictConfig) -> float | None:
    logging.captureWarnings(True)  # warnings reach train.log too
    route_lightning_logs()
    ignore_known_warnings()
    with run_errors_exit("lanelab-train"):
        metrics = train(validate(cfg))
    # The value a Hydra sweeper (e.g. optuna) optimises.
    return metrics.get("val/f1")


def main() -> None:
    run_hydra_tool("lanelab-train", _run)


if __name__ == "__main__":
    main()
