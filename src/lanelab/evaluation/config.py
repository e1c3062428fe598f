"""Typed schema of ``conf/eval.yaml`` and the checks run before anything is read.

The defaults live in ``conf/eval.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

from omegaconf import MISSING

from lanelab.config_checks import ConfigError, check_existing, load_config

MIN_PICTURE_HEIGHT = 64  # pixels: below this the lanes and titles cannot be told apart


@dataclass
class PicturesConfig:
    num_frames: int = MISSING
    height: int = MISSING


@dataclass
class EvalConfig:
    gt: Optional[str] = None
    pred: Optional[str] = None
    test_list: Optional[str] = None
    checkpoint: Optional[str] = None
    store: Optional[str] = None
    split: str = MISSING
    accelerator: str = MISSING
    out: str = MISSING
    long_range: bool = MISSING
    scenario_lists: Optional[str] = None
    images: Optional[str] = None
    blind_prior: bool = MISSING
    prior_store: Optional[str] = None
    error_budget: bool = MISSING
    format: str = MISSING
    without_ego_motion: Optional[str] = None
    pictures: PicturesConfig = field(default_factory=PicturesConfig)


FILE_OPTIONS = ("gt", "pred", "test_list")  # the prediction-files mode
FORMATS = ("openlane", "once")
ONCE_FILE_OPTIONS = ("gt", "pred")  # ONCE-3DLanes scores every label under gt: no test list
OPENLANE_ONLY = ("long_range", "scenario_lists", "images", "error_budget", "prior_store")  # not for format=once
EGO_MOTION_POLICIES = ("refuse", "single_frame")  # lanelab.experiment.ego_motion
CHECKPOINT_OPTIONS = ("checkpoint", "store")  # the checkpoint mode


def validate(cfg: EvalConfig) -> EvalConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    if cfg.format not in FORMATS:
        raise ConfigError(f"format={cfg.format!r} is not one of {', '.join(FORMATS)}")
    once = cfg.format == "once"
    files = ONCE_FILE_OPTIONS if once else FILE_OPTIONS
    modes = f"give {', '.join(files)} (prediction files) or checkpoint and store (a trained model)"
    checkpoint_mode = cfg.checkpoint is not None or cfg.store is not None
    chosen = CHECKPOINT_OPTIONS if checkpoint_mode else files
    unused = FILE_OPTIONS if checkpoint_mode else CHECKPOINT_OPTIONS + tuple(k for k in FILE_OPTIONS if k not in files)
    for key in chosen:
        if getattr(cfg, key) is None:
            raise ConfigError(f"{key}: missing ({modes})")
    for key in unused:
        if getattr(cfg, key) is not None:
            raise ConfigError(f"{key}: not used with {chosen[0]}=... ({modes})")
    if chosen is CHECKPOINT_OPTIONS:
        for key in ("long_range", "scenario_lists", "images"):
            if getattr(cfg, key):
                raise ConfigError(f"{key}: applies to prediction files; a checkpoint is scored with its "
                                  "model's metric settings and the store's images and tags")  # fmt: skip
    if once:
        for key in OPENLANE_ONLY:
            if getattr(cfg, key):
                raise ConfigError(f"{key}: applies to the OpenLane metric, not to format=once")
    if cfg.without_ego_motion is not None and cfg.without_ego_motion not in EGO_MOTION_POLICIES:
        raise ConfigError(f"without_ego_motion={cfg.without_ego_motion!r} is not one of "
                          f"{', '.join(EGO_MOTION_POLICIES)} (or null: the run config's)")
    if cfg.without_ego_motion is not None and cfg.checkpoint is None:
        raise ConfigError("without_ego_motion: applies to a checkpoint (how its model treats clips without ego motion)")
    check_existing("checkpoint", cfg.checkpoint, "file")
    check_existing("store", cfg.store, "folder")
    check_existing("gt", cfg.gt, "folder")
    check_existing("pred", cfg.pred, "folder")
    check_existing("test_list", cfg.test_list, "file")
    check_existing("scenario_lists", cfg.scenario_lists, "folder")
    check_existing("images", cfg.images, "folder")
    check_existing("prior_store", cfg.prior_store, "folder")
    if cfg.pictures.num_frames < 0:
        raise ConfigError(f"pictures.num_frames={cfg.pictures.num_frames} must be >= 0")
    if cfg.pictures.height < MIN_PICTURE_HEIGHT:
        raise ConfigError(f"pictures.height={cfg.pictures.height} must be >= {MIN_PICTURE_HEIGHT}")
    return cfg


SCHEMA_NAME = "eval_schema"  # the first entry of conf/eval.yaml's defaults


def load_eval_config(overrides: Sequence[str] = ()) -> EvalConfig:
    """Compose ``conf/eval.yaml`` with Hydra overrides and validate it, as ``lanelab-eval`` does."""
    return load_config("eval", SCHEMA_NAME, EvalConfig, validate, overrides)
