"""Typed schema of ``conf/openlane.yaml`` and the checks run before anything is written.

The defaults live in ``conf/openlane.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence

from omegaconf import MISSING

from data_ingest.dataset_adapter import check_splits
from lanelab.config_checks import ConfigError, check_existing, load_config  # noqa: F401 (ConfigError: validate's error, for callers)


@dataclass
class OpenLaneAdapterConfig:
    annotations: str = MISSING
    images: str = MISSING
    output: str = MISSING
    splits: Dict[str, str] = field(default_factory=dict)
    scenario_lists: Optional[str] = None
    scene_tags: Optional[str] = None


def validate(cfg: OpenLaneAdapterConfig) -> OpenLaneAdapterConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_existing("annotations", cfg.annotations, "folder")
    check_existing("images", cfg.images, "folder")
    check_existing("scenario_lists", cfg.scenario_lists, "folder")
    check_existing("scene_tags", cfg.scene_tags, "file")
    check_splits(cfg.splits, "OpenLane", "splits.validation=val")
    return cfg


SCHEMA_NAME = "openlane_schema"  # the first entry of conf/openlane.yaml's defaults


def load_openlane_config(overrides: Sequence[str] = ()) -> OpenLaneAdapterConfig:
    """Compose ``conf/openlane.yaml`` with Hydra overrides and validate it, as ``lanelab-openlane`` does."""
    return load_config("openlane", SCHEMA_NAME, OpenLaneAdapterConfig, validate, overrides)
