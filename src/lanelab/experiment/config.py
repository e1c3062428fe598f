"""Typed schema of ``conf/train.yaml`` and the checks run before anything is built.

Unlike the other tools (:mod:`lanelab.config_checks`), the config stays a DictConfig:
Hydra instantiates its groups.

The defaults live in ``conf/``; this module only says which top-level keys exist and their
types (OmegaConf rejects an unknown key or a wrong type by name while composing), and checks
every ``_target_`` node of the groups against the signature of what it builds
(:mod:`lanelab.experiment.targets`), so that a typo anywhere fails at start with its key.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

from hydra import compose, initialize_config_module
from omegaconf import MISSING, DictConfig

from lanelab.config_checks import ConfigError, check_known_keys, register_schema
from lanelab.evaluation.config import EGO_MOTION_POLICIES, FORMATS
from lanelab.experiment.run_names import register_resolvers
from lanelab.experiment.targets import TargetError, check_targets

SCHEMA_NAME = "train_schema"  # the first entry of conf/train.yaml's defaults
register_resolvers()  # conf/logger/*.yaml name runs with them


@dataclass
class SamplerGroup:
    train: Any = MISSING  # a partial sampler factory (conf/sampler/*.yaml)
    eval: Any = MISSING


@dataclass
class PathsConfig:
    log_dir: str = MISSING
    output_dir: str = MISSING
    checkpoint_dir: str = MISSING


@dataclass
class EvaluationConfig:
    enabled: bool = MISSING
    out: str = MISSING
    num_pictures: int = MISSING
    picture_height: int = MISSING
    blind_prior: bool = MISSING
    prior_store: str | None = None
    error_budget: bool = False  # a default: the run configs inside older checkpoints lack the key
    format: str = "openlane"  # openlane | once; a default for the same reason


@dataclass
class DemoConfig:
    """lanelab-demo's recipe (conf/experiment/demo.yaml); lanelab-train ignores it."""

    out: str = MISSING
    models: list[str] = MISSING
    columns: dict[str, list[str]] = MISSING
    synth: list[str] = MISSING
    train_logs: list[str] = MISSING
    test_logs: dict[str, list[str]] = MISSING
    ingest_train: list[str] = MISSING
    ingest_test: list[str] = MISSING
    train_store: Optional[str] = None


@dataclass
class TrainConfig:
    task_name: str = MISSING
    tags: list[str] = field(default_factory=list)
    seed: int = MISSING
    cpu_threads: int | None = None
    train: bool = MISSING
    test: bool = MISSING
    ckpt_path: str | None = None
    without_ego_motion: str = "refuse"  # a default: the run configs inside older checkpoints lack the key
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    # The groups: each is checked against what it builds (check_targets).
    data: Any = MISSING
    sampler: SamplerGroup = field(default_factory=SamplerGroup)
    model: Any = MISSING
    trainer: Any = MISSING
    logger: dict[str, Any] | None = None
    callbacks: dict[str, Any] | None = None
    paths: PathsConfig = field(default_factory=PathsConfig)
    demo: DemoConfig | None = None


def validate(cfg: DictConfig) -> DictConfig:
    """Check the composed config; raise :class:`ConfigError` naming the first bad key."""
    check_known_keys(cfg, TrainConfig)
    try:
        check_targets(cfg)
    except TargetError as err:
        raise ConfigError(str(err)) from None
    for group in ("logger", "callbacks"):
        for name, node in (cfg[group] or {}).items():
            if not isinstance(node, DictConfig) or "_target_" not in node:
                raise ConfigError(f"{group}.{name}: no _target_ (every entry of {group} is an object to build)")
    if not (cfg.train or cfg.test or cfg.evaluation.enabled):
        raise ConfigError("train, test and evaluation.enabled are all false: nothing to do")
    if not cfg.train and cfg.ckpt_path is None:
        raise ConfigError("ckpt_path: needed when train=false (the weights to test or evaluate)")
    if cfg.without_ego_motion not in EGO_MOTION_POLICIES:
        raise ConfigError(f"without_ego_motion={cfg.without_ego_motion!r} is not one of {', '.join(EGO_MOTION_POLICIES)}")
    if cfg.evaluation.format not in FORMATS:
        raise ConfigError(f"evaluation.format={cfg.evaluation.format!r} is not one of {', '.join(FORMATS)}")
    if cfg.cpu_threads is not None and cfg.cpu_threads < 1:
        raise ConfigError(f"cpu_threads={cfg.cpu_threads} must be >= 1 (or null)")
    if cfg.evaluation.num_pictures < 0:
        raise ConfigError(f"evaluation.num_pictures={cfg.evaluation.num_pictures} must be >= 0")
    return cfg


def load_train_config(overrides: Sequence[str] = ()) -> DictConfig:
    """Compose ``conf/train.yaml`` with Hydra overrides and validate it, as ``lanelab-train``
    does, for scripts and tests. Outside a Hydra run there is no run folder: give
    ``paths.output_dir=DIR``."""
    register_schema(SCHEMA_NAME, TrainConfig)
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name="train", overrides=list(overrides))
    return validate(cfg)
