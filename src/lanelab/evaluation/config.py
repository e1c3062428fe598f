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
    pictures: PicturesConfig = field(default_factory=PicturesConfig)


FILE_OPTIONS = ("gt", "pred", "test_list")  # the prediction-files mode
CHECKPOINT_OPTIONS = ("checkpoint", "store")  # the checkpoint mode


def validate(cfg: EvalConfig) -> EvalConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    modes = "give gt, pred and test_list (prediction files) or checkpoint and store (a trained model)"
    chosen = CHECKPOINT_OPTIONS if cfg.checkpoint is not None or cfg.store is not None else FILE_OPTIONS
    other = FILE_OPTIONS if chosen is CHECKPOINT_OPTIONS else CHECKPOINT_OPTIONS
    for key in chosen:
        if getattr(cfg, key) is None:
            raise ConfigError(f"{key}: missing ({modes})")
    for key in other:
        if getattr(cfg, key) is not None:
            raise ConfigError(f"{key}: not used with {chosen[0]}=... ({modes})")
    if chosen is CHECKPOINT_OPTIONS:
        for key in ("long_range", "scenario_lists", "images"):
            if getattr(cfg, key):
                raise ConfigError(f"{key}: applies to prediction files; a checkpoint is scored with its "
                                  "model's metric settings and the store's images and tags")  # fmt: skip
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
