"""Typed schema of ``conf/synth.yaml`` and the checks run before anything is written.

The defaults live in ``conf/synth.yaml``; this module only says which keys exist, their
types (OmegaConf rejects an unknown key or a wrong type by name) and which values make
sense (:func:`validate`).
"""

from __future__ import annotations

import calendar
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Optional, Sequence

from omegaconf import MISSING

from data_ingest.contract import FramesConfig, TopicsConfig, check_names
from lanelab.config_checks import ConfigError, check_choice, check_positive, load_config

ENCODINGS = ("ros2", "foxglove")
FOXGLOVE_SCHEMAS = ("protobuf", "json")
IMAGE_FORMATS = ("jpeg", "png", "raw")
DETECTOR_NOISE = ("row", "isotropic")
COMPRESSIONS = ("zstd", "lz4", "none")
LABEL_FRAMES = ("base_link", "odom")
ENVIRONMENTS = ("highway", "urban", "rural")
DAYTIMES = ("day", "night")
WEATHERS = ("sun", "rain", "fog", "snow")
MAX_LANES = 6


@dataclass
class CameraConfig:
    width: int = MISSING
    height: int = MISSING
    hfov_deg: float = MISSING
    mount_height_m: float = MISSING
    mount_forward_m: float = MISSING
    pitch_deg: float = MISSING
    frame_id: str = MISSING


@dataclass
class WorldConfig:
    environment: str = MISSING
    daytime: str = MISSING
    weather: str = MISSING
    num_lanes: Optional[int] = None
    lane_width_m: list[float] = field(default_factory=lambda: [3.0, 4.0])
    min_curve_radius_m: float = MISSING
    max_straight_m: Optional[float] = None
    traffic_density: float = MISSING
    max_range_m: float = MISSING
    ego_speed_mps: Optional[float] = None


@dataclass
class SynthConfig:
    output_dir: str = MISSING
    num_logs: int = MISSING
    duration_s: float = MISSING
    seed: int = MISSING
    encoding: str = MISSING
    foxglove_schema: str = MISSING
    image_format: str = MISSING
    jpeg_quality: int = MISSING
    fps: float = MISSING
    start_time: str = MISSING
    tf_rate_hz: float = MISSING
    label_every: int = MISSING
    labels_frame: str = MISSING
    compression: str = MISSING
    chunk_size: int = MISSING
    workers: int = MISSING
    preview: bool = MISSING
    overwrite: bool = MISSING
    detector_noise: str = MISSING
    camera: CameraConfig = field(default_factory=CameraConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    topics: TopicsConfig = field(default_factory=TopicsConfig)
    frames: FramesConfig = field(default_factory=FramesConfig)


def _choice(key: str, value: str, choices: tuple[str, ...], allow_random: bool = False) -> None:
    check_choice(key, value, choices + (("random",) if allow_random else ()))


def validate(cfg: SynthConfig) -> SynthConfig:
    """Check every option; raise :class:`ConfigError` naming the first bad key."""
    check_positive("num_logs", cfg.num_logs)
    check_positive("duration_s", cfg.duration_s)
    check_positive("fps", cfg.fps)
    check_positive("tf_rate_hz", cfg.tf_rate_hz)
    check_positive("label_every", cfg.label_every)
    check_positive("chunk_size", cfg.chunk_size)
    check_positive("workers", cfg.workers)
    start_time_ns(cfg, 0)
    if not 1 <= cfg.jpeg_quality <= 100:
        raise ConfigError(f"jpeg_quality={cfg.jpeg_quality} must be in 1..100")
    _choice("encoding", cfg.encoding, ENCODINGS)
    _choice("foxglove_schema", cfg.foxglove_schema, FOXGLOVE_SCHEMAS)
    _choice("image_format", cfg.image_format, IMAGE_FORMATS)
    _choice("detector_noise", cfg.detector_noise, DETECTOR_NOISE)
    _choice("compression", cfg.compression, COMPRESSIONS)
    _choice("labels_frame", cfg.labels_frame, LABEL_FRAMES)

    cam = cfg.camera
    for key in ("width", "height", "hfov_deg", "mount_height_m"):
        check_positive(f"camera.{key}", getattr(cam, key))
    if cam.width < 16 or cam.height < 16:
        raise ConfigError(f"camera resolution {cam.height}x{cam.width} is too small (at least 16x16)")
    if cam.hfov_deg >= 170:
        raise ConfigError(f"camera.hfov_deg={cam.hfov_deg} must be < 170 for a pinhole camera")
    if not -30 <= cam.pitch_deg <= 30:
        raise ConfigError(f"camera.pitch_deg={cam.pitch_deg} must be within [-30, 30]")

    world = cfg.world
    _choice("world.environment", world.environment, ENVIRONMENTS, allow_random=True)
    _choice("world.daytime", world.daytime, DAYTIMES, allow_random=True)
    _choice("world.weather", world.weather, WEATHERS, allow_random=True)
    if world.num_lanes is not None and not 1 <= world.num_lanes <= MAX_LANES:
        raise ConfigError(f"world.num_lanes={world.num_lanes} must be in 1..{MAX_LANES} (or null for random)")
    if len(world.lane_width_m) != 2 or not 2.5 <= world.lane_width_m[0] <= world.lane_width_m[1] <= 5.0:
        raise ConfigError(f"world.lane_width_m={list(world.lane_width_m)} must be [min, max] within [2.5, 5.0]")
    if world.min_curve_radius_m < 50:
        raise ConfigError(f"world.min_curve_radius_m={world.min_curve_radius_m} must be >= 50")
    if world.max_straight_m is not None and world.max_straight_m < 0:
        raise ConfigError(f"world.max_straight_m={world.max_straight_m} must be >= 0 (or null)")
    if world.traffic_density < 0:
        raise ConfigError(f"world.traffic_density={world.traffic_density} must be >= 0")
    check_positive("world.max_range_m", world.max_range_m)
    if world.ego_speed_mps is not None and not 0 < world.ego_speed_mps <= 60:
        raise ConfigError(f"world.ego_speed_mps={world.ego_speed_mps} must be in (0, 60] (or null for the environment's)")
    check_names(cfg.topics, cfg.frames)
    return cfg


SCHEMA_NAME = "synth_schema"  # the first entry of conf/synth.yaml's defaults


def load_synth_config(overrides: Sequence[str] = ()) -> SynthConfig:
    """Compose ``conf/synth.yaml`` with Hydra overrides and validate it, as ``lanelab-synth`` does."""
    return load_config("synth", SCHEMA_NAME, SynthConfig, validate, overrides)


def start_time_ns(cfg: SynthConfig, log_index: int) -> int:
    """Sensor time (ns since the Unix epoch) of log log_index's first frame: ``start_time``, and
    an hour later for each log before it (drives recorded one after another). A time without a
    zone is UTC. Raises ConfigError for a value that is no ISO 8601 date and time."""
    try:
        start = datetime.fromisoformat(cfg.start_time)
    except (TypeError, ValueError):
        raise ConfigError(f"start_time={cfg.start_time!r} is no ISO 8601 date and time (e.g. 2026-03-02T09:00:00Z)") from None
    if start.tzinfo is None:
        start = start.replace(tzinfo=timezone.utc)
    seconds = calendar.timegm(start.utctimetuple())
    return (seconds + 3600 * log_index) * 1_000_000_000 + start.microsecond * 1000
