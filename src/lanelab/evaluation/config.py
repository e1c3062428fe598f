"""Typed schema of ``conf/eval.yaml`` and the checks run before anything is read.

The defaults live in ``conf/eval.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

from hydra import compose, initialize_config_module
from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, OmegaConf

MIN_PICTURE_HEIGHT = 64  # pixels: below this the lanes and titles cannot be told apart


class ConfigError(ValueError):
    """An option of ``lanelab-eval`` has a value that cannot work; names the key."""


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


def _existing(key: str, value: str | None, kind: str) -> None:
    if value is None:
        return
    path = Path(value)
    if not (path.is_dir() if kind == "folder" else path.is_file()):
        raise ConfigError(f"{key}={value!r} is not an existing {kind}")


def validate(cfg: EvalConfig) -> EvalConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    _existing("gt", cfg.gt, "folder")
    _existing("pred", cfg.pred, "folder")
    _existing("test_list", cfg.test_list, "file")
    _existing("scenario_lists", cfg.scenario_lists, "folder")
    _existing("images", cfg.images, "folder")
    if cfg.pictures.num_frames < 0:
        raise ConfigError(f"pictures.num_frames={cfg.pictures.num_frames} must be >= 0")
    if cfg.pictures.height < MIN_PICTURE_HEIGHT:
        raise ConfigError(f"pictures.height={cfg.pictures.height} must be >= {MIN_PICTURE_HEIGHT}")
    return cfg


def register_schema() -> None:
    """Make the schema known to Hydra as ``eval_schema`` (the first entry of conf/eval.yaml's defaults)."""
    ConfigStore.instance().store(name="eval_schema", node=EvalConfig)


def load_eval_config(overrides: Sequence[str] = ()) -> EvalConfig:
    """Compose ``conf/eval.yaml`` with Hydra overrides and validate it, as ``lanelab-eval`` does.

    For scripts and tests that evaluate without the command line.
    """
    register_schema()
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name="eval", overrides=list(overrides))
    return validate(OmegaConf.to_object(cfg))
