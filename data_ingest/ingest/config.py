"""Typed schema of ``conf/ingest.yaml`` and the checks run before any log is read.

The defaults live in ``conf/ingest.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`). Topic and frame names are the drive-log contract's
(:mod:`data_ingest.contract`), shared with ``lanelab-synth``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Optional, Protocol, Sequence

from omegaconf import MISSING

from data_ingest.autolabel.config import AutolabelConfig, validate_autolabel
from data_ingest.contract import FramesConfig, TopicsConfig, check_names
from lanelab.config_checks import ConfigError, check_choice, check_positive, load_config

SPLIT_BY = ("log", "clip")


@dataclass
class TolerancesConfig:
    label_s: float = MISSING
    calibration_s: Optional[float] = None
    tags_s: float = MISSING
    max_tf_gap_s: Optional[float] = MISSING
    tf_agreement: Optional[float] = MISSING


@dataclass
class ClipsConfig:
    gap_s: float = MISSING
    max_length_s: float = MISSING
    target_fps: Optional[float] = None


@dataclass
class SplitConfig:
    by: str = MISSING
    seed: int = MISSING
    train: float = MISSING
    val: float = MISSING
    test: float = MISSING


@dataclass
class IngestConfig:
    input: str = MISSING
    output: str = MISSING
    workers: int = MISSING
    overwrite: bool = MISSING
    verify: bool = MISSING
    topics: TopicsConfig = field(default_factory=TopicsConfig)
    frames: FramesConfig = field(default_factory=FramesConfig)
    tolerances: TolerancesConfig = field(default_factory=TolerancesConfig)
    clips: ClipsConfig = field(default_factory=ClipsConfig)
    split: SplitConfig = field(default_factory=SplitConfig)
    autolabel: AutolabelConfig = field(default_factory=AutolabelConfig)


AUTOLABEL_OPTION = "autolabel"  # the manifest's options key of a store whose labels were auto-labeled


class LogReading(Protocol):
    """The options that say how a drive log is read into frames, those of lanelab-ingest and
    lanelab-predict alike: topic and frame names, matching tolerances, where clips are cut."""

    topics: TopicsConfig
    frames: FramesConfig
    tolerances: TolerancesConfig
    clips: ClipsConfig


def store_options(cfg: IngestConfig) -> dict[str, Any]:
    """The options that shape a store's contents (recorded in its manifest); not input, output, workers, verify.

    With ``autolabel.enabled`` they hold ``autolabel``: the labels came from the logs' 2D
    detections and trajectories (its options and where the detections came from), not from
    their ``/lanes``. A store of true labels has no such key, as stores had before it existed.
    """
    options = {key: asdict(getattr(cfg, key)) for key in ("topics", "frames", "tolerances", "clips", "split")}
    if not cfg.autolabel.enabled:
        del options["topics"]["occluders"]  # read by the auto-labeler alone; stores made before it existed stay valid
    if cfg.autolabel.enabled:
        settings = {key: value for key, value in asdict(cfg.autolabel).items()
                    if key not in ("enabled", "report", "report_dir", "pictures")}  # these shape no label
        options[AUTOLABEL_OPTION] = {"labels_from": f"auto-labeling (SparseLaneSTP §4) of the 2D lane detections "
                                                    f"on {cfg.topics.lanes2d} along the ego trajectory",
                                     **settings}
    return options


def validate(cfg: IngestConfig) -> IngestConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    if not cfg.input:
        raise ConfigError("input is empty: give a log, a folder or a glob")
    if not cfg.output:
        raise ConfigError("output is empty: give the clip store directory")
    check_positive("workers", cfg.workers)
    check_reading(cfg)
    check_choice("split.by", cfg.split.by, SPLIT_BY)
    ratios = {name: getattr(cfg.split, name) for name in ("train", "val", "test")}
    if any(value < 0 for value in ratios.values()) or abs(sum(ratios.values()) - 1) > 1e-6:
        raise ConfigError(f"split ratios {ratios} must be >= 0 and sum to 1")
    validate_autolabel(cfg.autolabel)
    return cfg


def check_reading(cfg: LogReading) -> None:
    """Check the options of :class:`LogReading`; raise :class:`ConfigError` naming the first bad key."""
    for key in ("label_s", "calibration_s", "tags_s", "max_tf_gap_s", "tf_agreement"):
        value = getattr(cfg.tolerances, key)
        if value is not None and value < 0:
            raise ConfigError(f"tolerances.{key}={value!r} must be >= 0")
    check_positive("clips.gap_s", cfg.clips.gap_s)
    check_positive("clips.max_length_s", cfg.clips.max_length_s)
    check_positive("clips.target_fps", cfg.clips.target_fps)
    if cfg.clips.target_fps is not None and 1 / cfg.clips.target_fps >= cfg.clips.gap_s:
        raise ConfigError(f"clips.target_fps={cfg.clips.target_fps} keeps frames further apart than "
                          f"clips.gap_s={cfg.clips.gap_s}: every frame would be its own clip")
    check_names(cfg.topics, cfg.frames)


SCHEMA_NAME = "ingest_schema"  # the first entry of conf/ingest.yaml's defaults


def load_ingest_config(overrides: Sequence[str] = ()) -> IngestConfig:
    """Compose ``conf/ingest.yaml`` with Hydra overrides and validate it, as ``lanelab-ingest`` does."""
    return load_config("ingest", SCHEMA_NAME, IngestConfig, validate, overrides)
