"""A run built from its composed config, and the config every checkpoint carries.

:func:`build_run` instantiates what a config describes (the datamodule, the LightningModule, the
callbacks, the loggers and the Trainer; Hydra instantiates, nothing here holds a default):
``lanelab-train`` fits, tests and evaluates it (:mod:`lanelab.experiment.train`), the evaluation
of a checkpoint predicts with it (:mod:`lanelab.experiment.evaluate`). Every checkpoint of a
run holds the run's resolved config (:class:`RunConfigInCheckpoint`), which :func:`run_config`
reads back, brought up to date where older runs wrote keys that are gone.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import torch
from hydra.utils import instantiate
from lightning.pytorch.loggers import Logger
from omegaconf import DictConfig, OmegaConf

from lanelab.config_checks import ConfigError
from lanelab.experiment.checkpoints import load_checkpoint
from lanelab.experiment.ego_motion import apply_ego_motion_policy
from lanelab.lightning.csv_logger import HistoryAtCheckpoint

CONFIG_KEY = "lanelab_config"
# The ``_target_`` names that run configs of earlier versions hold, where they moved when the models
# were laid out one package per detector (issue 41): old dotted name -> today's. Every name a
# shipped config ever gave is here; :func:`read_checkpoint` maps them, so old checkpoints build.
MOVED_TARGETS = {
    "lanelab.models.SparseLaneSTP": "lanelab.models.sparselanestp.SparseLaneSTP",
    "lanelab.models.SparseLaneSTPLoss": "lanelab.models.sparselanestp.SparseLaneSTPLoss",
    "lanelab.models.losses.SparseLaneSTPCriterion": "lanelab.models.sparselanestp.SparseLaneSTPCriterion",
    "lanelab.models.losses.InstanceMaskLoss": "lanelab.models.sparselanestp.InstanceMaskLoss",
    "lanelab.models.losses.LateralOffsetLoss": "lanelab.models.sparselanestp.LateralOffsetLoss",
    "lanelab.models.Bi2Lane": "lanelab.models.bi2lane.Bi2Lane",
    "lanelab.models.losses.Bi2LaneCriterion": "lanelab.models.bi2lane.Bi2LaneCriterion",
    "lanelab.models.HungarianMatcher": "lanelab.models.parts.HungarianMatcher",
}


@dataclass
class Run:
    """What a run config builds."""

    datamodule: pl.LightningDataModule
    module: pl.LightningModule
    trainer: pl.Trainer
    loggers: list[Logger]


def build_run(cfg: DictConfig) -> Run:
    """Seed, set the CPU threads, and build a composed, validated config's run; the loggers
    get the resolved config as their hyperparameters.

    The store is checked first, for the stages the run will go through (:func:`stages`),
    before the model and the Trainer are built: :class:`~lanelab.store.ManifestError` (no
    store or an unreadable one), :class:`~lanelab.store.DataError` (a split without clips, or
    windows its clips cannot give), ConfigError (clips without ego motion for a temporal model,
    unless ``without_ego_motion=single_frame``: :mod:`lanelab.experiment.ego_motion`)."""
    pl.seed_everything(cfg.seed, workers=True, verbose=False)
    if cfg.cpu_threads is not None:
        torch.set_num_threads(cfg.cpu_threads)
    apply_ego_motion_policy(cfg, stages(cfg))  # before the datamodule reads num_frames and the samplers
    datamodule = instantiate(cfg.data)
    datamodule.check(stages(cfg))
    module = instantiate(cfg.model)
    callbacks = [instantiate(node) for node in (cfg.callbacks or {}).values()]
    callbacks += [RunConfigInCheckpoint(cfg), HistoryAtCheckpoint()]
    loggers = [instantiate(node) for node in (cfg.logger or {}).values()]
    trainer = instantiate(cfg.trainer, callbacks=callbacks, logger=loggers or False)
    for logger in loggers:
        logger.log_hyperparams(OmegaConf.to_container(cfg, resolve=True))
    return Run(datamodule, module, trainer, loggers)


def stages(cfg: DictConfig) -> list[str]:
    """The datamodule's stages a run goes through: fitting reads train and val, testing test,
    the evaluation predict."""
    return (["train", "val"] if cfg.train else []) + (["test"] if cfg.test else []) + \
        (["predict"] if cfg.evaluation.enabled else [])


class RunConfigInCheckpoint(pl.Callback):
    """Writes the run's resolved config into every checkpoint (key ``lanelab_config``), so that
    ``lanelab-eval checkpoint=...`` rebuilds the same model and data pipeline from the file alone."""

    def __init__(self, cfg: DictConfig) -> None:
        self.config = OmegaConf.to_container(cfg, resolve=True)

    def on_save_checkpoint(self, trainer: pl.Trainer, module: pl.LightningModule, checkpoint: dict) -> None:
        checkpoint[CONFIG_KEY] = self.config


def run_config(checkpoint: str | Path) -> dict[str, Any]:
    """The resolved run config lanelab-train wrote into the checkpoint, in today's keys.
    Raises ConfigError naming the checkpoint when it holds none."""
    return read_checkpoint(checkpoint)[CONFIG_KEY]


def read_checkpoint(checkpoint: str | Path) -> dict[str, Any]:
    """A lanelab-train checkpoint's content (on the CPU, its tensors mapped from the file), its
    run config (``CONFIG_KEY``) in today's keys. Raises ConfigError naming the checkpoint when it
    cannot be read or holds no run config."""
    content = load_checkpoint(checkpoint, "checkpoint")
    if CONFIG_KEY not in content:
        raise ConfigError(f"checkpoint={checkpoint}: holds no lanelab run config (not written by lanelab-train)")
    content[CONFIG_KEY] = _up_to_date(content[CONFIG_KEY])
    return content


def _up_to_date(config: dict[str, Any]) -> dict[str, Any]:
    """An older run config with the data keys of today: the Catmull-Rom targets
    (``data.control_points``) are gone, and the samplers' ``flip`` is given where older configs
    left it to a default (False). Bi²Lane's offset heads had the other heads' hidden width before
    ``model.net.offset_hidden_dim`` was split off. Keys added since, with the behaviour of runs
    before them: no lateral-shift augmentation (``data.lateral_shift``), clips without ego motion
    refused (``without_ego_motion``), OpenLane evaluation (``evaluation.format``). The model of
    older runs, ``lanelab.lightning.SparseLaneSTPModule``, still builds (lanelab.lightning.legacy),
    and the classes that moved are named where they are now (``MOVED_TARGETS``)."""
    _move_targets(config)
    data, sampler = config.get("data", {}), config.get("sampler", {})
    data.pop("control_points", None)
    if "_target_" in data:
        data.setdefault("lateral_shift", None)
    config.setdefault("without_ego_motion", "refuse")
    if isinstance(config.get("evaluation"), dict):
        config["evaluation"].setdefault("format", "openlane")
    for node in (data.get("train_sampler"), data.get("eval_sampler"), sampler.get("train"), sampler.get("eval")):
        if isinstance(node, dict):
            node.setdefault("flip", False)
    net = config.get("model", {}).get("net", {})
    if isinstance(net, dict) and str(net.get("_target_", "")).endswith(".Bi2Lane") and "head_hidden_dim" in net:
        net.setdefault("offset_hidden_dim", net["head_hidden_dim"])
    return config


def _move_targets(node: Any) -> None:
    """Every ``_target_`` of nested dicts and lists that ``MOVED_TARGETS`` names, renamed in place."""
    if isinstance(node, dict):
        if node.get("_target_") in MOVED_TARGETS:
            node["_target_"] = MOVED_TARGETS[node["_target_"]]
        children = node.values()
    elif isinstance(node, list):
        children = node
    else:
        return
    for child in children:
        _move_targets(child)
