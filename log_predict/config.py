"""Typed schema of ``conf/predict.yaml`` and the checks run before any log is read.

The defaults live in ``conf/predict.yaml``; this module says which keys exist and their types,
and :func:`validate` rejects values that cannot work, naming the key. Logs are read with the
ingestor's options (topics, frames, tolerances, clips: :class:`data_ingest.ingest.config.LogReading`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from omegaconf import MISSING

from data_ingest.contract import FramesConfig, TopicsConfig
from data_ingest.ingest.config import ClipsConfig, TolerancesConfig, check_reading
from lanelab.config_checks import ConfigError, check_choice, check_existing, check_positive, load_config
from lanelab.deploy.devices import ACCELERATORS


@dataclass
class PredictionsConfig:
    """The topics written and how their lanes are drawn."""

    lanes: str = MISSING
    scene: str = MISSING
    annotations: str = MISSING
    ground_truth: str = MISSING
    line_width: float = MISSING
    annotation_width: float = MISSING


@dataclass
class PredictConfig:
    checkpoint: str = MISSING
    input: str = MISSING
    output: str = MISSING
    merge: bool = MISSING
    accelerator: str = MISSING
    preview_frames: int = MISSING
    predictions: PredictionsConfig = field(default_factory=PredictionsConfig)
    topics: TopicsConfig = field(default_factory=TopicsConfig)
    frames: FramesConfig = field(default_factory=FramesConfig)
    tolerances: TolerancesConfig = field(default_factory=TolerancesConfig)
    clips: ClipsConfig = field(default_factory=ClipsConfig)

    def written_topics(self) -> tuple[str, str, str, str]:
        """The topics lanelab-predict writes (the last only for a log with labels)."""
        options = self.predictions
        return options.lanes, options.scene, options.annotations, options.ground_truth

    def copied_topics(self) -> tuple[str, ...]:
        """What a file without merge copies from its log: what Foxglove needs to show the lanes."""
        return self.topics.image, self.topics.calibration, self.topics.tf, self.topics.tf_static


def validate(cfg: PredictConfig) -> PredictConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_existing("checkpoint", cfg.checkpoint, "file")
    if not cfg.input:
        raise ConfigError("input is empty: give a log, a folder or a glob")
    if not cfg.output:
        raise ConfigError("output is empty: give the folder the predicted logs go to")
    check_choice("accelerator", cfg.accelerator, ACCELERATORS)
    if cfg.preview_frames < 0:
        raise ConfigError(f"preview_frames={cfg.preview_frames} must be >= 0")
    check_reading(cfg)
    check_positive("predictions.line_width", cfg.predictions.line_width)
    check_positive("predictions.annotation_width", cfg.predictions.annotation_width)
    written = dict(zip(("lanes", "scene", "annotations", "ground_truth"), cfg.written_topics()))
    for key, topic in written.items():
        if not topic:
            raise ConfigError(f"predictions.{key} is empty")
        if topic in cfg.copied_topics():
            raise ConfigError(f"predictions.{key}={topic} is a topic of the log the output copies; name another")
    if len(set(written.values())) < len(written):
        raise ConfigError(f"predictions.lanes, .scene, .annotations and .ground_truth must be four topics, got {written}")
    return cfg


SCHEMA_NAME = "predict_schema"  # the first entry of conf/predict.yaml's defaults


def load_predict_config(overrides: Sequence[str] = ()) -> PredictConfig:
    """Compose ``conf/predict.yaml`` with Hydra overrides and validate it, as ``lanelab-predict`` does."""
    return load_config("predict", SCHEMA_NAME, PredictConfig, validate, overrides)
