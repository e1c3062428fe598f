"""Typed schema of ``conf/openlane.yaml`` and the checks run before anything is written.

The defaults live in ``conf/openlane.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Optional, Sequence

from hydra import compose, initialize_config_module
from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, OmegaConf

from data_ingest.synth.config import ConfigError
from lanelab.data.clip_store import SPLITS


@dataclass
class OpenLaneAdapterConfig:
    annotations: str = MISSING
    images: str = MISSING
    output: str = MISSING
    splits: Dict[str, str] = field(default_factory=dict)
    scenario_lists: Optional[str] = None
    scene_tags: Optional[str] = None


def _existing(key: str, value: str | None, kind: str) -> None:
    if value is None:
        return
    path = Path(value)
    if not (path.is_dir() if kind == "folder" else path.is_file()):
        raise ConfigError(f"{key}={value!r} is not an existing {kind}")


def validate(cfg: OpenLaneAdapterConfig) -> OpenLaneAdapterConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    _existing("annotations", cfg.annotations, "folder")
    _existing("images", cfg.images, "folder")
    _existing("scenario_lists", cfg.scenario_lists, "folder")
    _existing("scene_tags", cfg.scene_tags, "file")
    if not cfg.splits:
        raise ConfigError("splits is empty: name at least one OpenLane split folder, e.g. splits.validation=val")
    for folder, split in cfg.splits.items():
        if split not in SPLITS:
            raise ConfigError(f"splits.{folder}={split!r} is not one of {', '.join(SPLITS)}")
    return cfg


def register_schema() -> None:
    """Make the schema known to Hydra as ``openlane_schema`` (the first entry of conf/openlane.yaml's defaults)."""
    ConfigStore.instance().store(name="openlane_schema", node=OpenLaneAdapterConfig)


def load_openlane_config(overrides: Sequence[str] = ()) -> OpenLaneAdapterConfig:
    """Compose ``conf/openlane.yaml`` with Hydra overrides and validate it, as ``lanelab-openlane`` does."""
    register_schema()
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name="openlane", overrides=list(overrides))
    return validate(OmegaConf.to_object(cfg))
