"""Typed schema of ``conf/export.yaml`` and the checks run before the checkpoint is read."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from omegaconf import MISSING

from lanelab.config_checks import ConfigError, check_choice, check_existing, check_positive, load_config

FORMATS = ("onnx", "torch")


@dataclass
class CheckConfig:
    frames: int = MISSING
    tolerance: float = MISSING


@dataclass
class ExportConfig:
    checkpoint: str = MISSING
    format: str = MISSING
    out: str = MISSING
    batch_size: int = MISSING
    check: CheckConfig = field(default_factory=CheckConfig)


def validate(cfg: ExportConfig) -> ExportConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_existing("checkpoint", cfg.checkpoint, "file")
    check_choice("format", cfg.format, FORMATS)
    if not cfg.out:
        raise ConfigError("out is empty: give the file to write")
    check_positive("batch_size", cfg.batch_size)
    if cfg.check.frames < 0:
        raise ConfigError(f"check.frames={cfg.check.frames} must be >= 0")
    check_positive("check.tolerance", cfg.check.tolerance)
    return cfg


SCHEMA_NAME = "export_schema"  # the first entry of conf/export.yaml's defaults


def load_export_config(overrides: Sequence[str] = ()) -> ExportConfig:
    """Compose ``conf/export.yaml`` with Hydra overrides and validate it, as ``lanelab-export`` does."""
    return load_config("export", SCHEMA_NAME, ExportConfig, validate, overrides)
