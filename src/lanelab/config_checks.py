"""Typed Hydra configs of lanelab's command-line tools: one error, one loader, shared checks.

Each tool keeps its defaults in ``conf/<tool>.yaml`` and its schema (which keys exist and
their types) in a dataclass; OmegaConf then rejects an unknown key or a wrong type by
name, and the tool's ``validate`` uses the checks below to reject values that cannot
work, naming the key, before anything is read or written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence, TypeVar

from hydra import compose, initialize_config_module
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

Config = TypeVar("Config")


class ConfigError(ValueError):
    """An option has a value that cannot work; the message names the key."""


def register_schema(name: str, schema: type) -> None:
    """Make ``schema`` known to Hydra as ``name`` (the first entry of its yaml's defaults list)."""
    ConfigStore.instance().store(name=name, node=schema)


def load_config(config_name: str, schema_name: str, schema: type[Config],
                validate: Callable[[Config], Config], overrides: Sequence[str] = ()) -> Config:
    """Compose ``conf/<config_name>.yaml`` with Hydra overrides and validate it, as its CLI does.

    For scripts, benchmarks and tests that run a tool without the command line.
    """
    register_schema(schema_name, schema)
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name=config_name, overrides=list(overrides))
    return validate(OmegaConf.to_object(cfg))


def check_positive(key: str, value: float | None) -> None:
    """``value`` must be > 0 (None, for an optional key, passes)."""
    if value is not None and not value > 0:
        raise ConfigError(f"{key}={value!r} must be > 0")


def check_choice(key: str, value: str, choices: Sequence[str]) -> None:
    if value not in choices:
        raise ConfigError(f"{key}={value!r} is not one of {', '.join(choices)}")


def check_existing(key: str, value: str | None, kind: str) -> None:
    """``value`` must name an existing ``kind`` ("folder" or "file"); None passes."""
    if value is None:
        return
    path = Path(value)
    if not (path.is_dir() if kind == "folder" else path.is_file()):
        raise ConfigError(f"{key}={value!r} is not an existing {kind}")
