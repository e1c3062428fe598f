"""Typed schema of ``conf/once.yaml`` and the checks run before anything is written.

The defaults live in ``conf/once.yaml``; this module only says which keys exist, their types
and which values make sense (:func:`validate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence

from omegaconf import MISSING

from data_ingest.dataset_adapter import check_splits
from lanelab.config_checks import ConfigError, check_existing, load_config


@dataclass
class CameraConfig:
    height: float = MISSING  # metres above the lane-frame origin
    pitch_deg: float = MISSING  # about the lane frame's x axis, positive looking up


@dataclass
class OnceAdapterConfig:
    root: str = MISSING
    output: str = MISSING
    images: Optional[str] = None
    poses: Optional[str] = None
    splits: Dict[str, str] = field(default_factory=dict)
    camera: CameraConfig = field(default_factory=CameraConfig)


def validate(cfg: OnceAdapterConfig) -> OnceAdapterConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_existing("root", cfg.root, "folder")
    check_existing("images", cfg.images, "folder")
    check_existing("poses", cfg.poses, "folder")
    check_splits(cfg.splits, "ONCE-3DLanes", "splits.val=val")
    if not (math.isfinite(cfg.camera.height) and cfg.camera.height > 0):
        raise ConfigError(f"camera.height={cfg.camera.height} must be a positive number of metres")
    if not (math.isfinite(cfg.camera.pitch_deg) and abs(cfg.camera.pitch_deg) < 45):
        raise ConfigError(f"camera.pitch_deg={cfg.camera.pitch_deg} must be within (-45, 45) degrees")
    return cfg


SCHEMA_NAME = "once_schema"  # the first entry of conf/once.yaml's defaults


def load_once_config(overrides: Sequence[str] = ()) -> OnceAdapterConfig:
    """Compose ``conf/once.yaml`` with Hydra overrides and validate it, as ``lanelab-once`` does."""
    return load_config("once", SCHEMA_NAME, OnceAdapterConfig, validate, overrides)
