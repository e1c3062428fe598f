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
    gt: str = MISSING
    pred: str = MISSING
    test_list: str = MISSING
    out: str = MISSING
    long_range: bool = MISSING
    scenario_lists: Optional[str] = None
    images: Optional[str] = None
    pictures: PicturesConfig = field(default_factory=PicturesConfig)


def validate(cfg: EvalConfig) -> EvalConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_existing("gt", cfg.gt, "folder")
    check_existing("pred", cfg.pred, "folder")
    check_existing("test_list", cfg.test_list, "file")
    check_existing("scenario_lists", cfg.scenario_lists, "folder")
    check_existing("images", cfg.images, "folder")
    if cfg.pictures.num_frames < 0:
        raise ConfigError(f"pictures.num_frames={cfg.pictures.num_frames} must be >= 0")
    if cfg.pictures.height < MIN_PICTURE_HEIGHT:
        raise ConfigError(f"pictures.height={cfg.pictures.height} must be >= {MIN_PICTURE_HEIGHT}")
    return cfg


SCHEMA_NAME = "eval_schema"  # the first entry of conf/eval.yaml's defaults


def load_eval_config(overrides: Sequence[str] = ()) -> EvalConfig:
    """Compose ``conf/eval.yaml`` with Hydra overrides and validate it, as ``lanelab-eval`` does."""
    return load_config("eval", SCHEMA_NAME, EvalConfig, validate, overrides)
