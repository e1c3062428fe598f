"""Typed schema of the ``autolabel`` group of ``conf/ingest.yaml`` and its checks.

The defaults live in ``conf/ingest.yaml`` (read it for what each option does); this module
says which keys exist, their types, and which values can work (:func:`validate_autolabel`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional

from omegaconf import MISSING

from lanelab.config_checks import ConfigError, check_positive


@dataclass
class AutolabelConfig:
    enabled: bool = MISSING
    range_m: float = MISSING
    min_reach_m: Optional[float] = None
    min_score: float = MISSING
    projection_range_m: List[float] = MISSING
    pixel_noise_px: float = MISSING
    max_point_std_m: float = MISSING
    node_spacing_m: float = MISSING
    gate_m: float = MISSING
    category_penalty_m: float = MISSING
    confirm_hits: int = MISSING
    max_misses: int = MISSING
    merge_m: float = MISSING
    min_length_m: float = MISSING
    max_std_m: float = MISSING
    max_gap_m: float = MISSING
    process_noise_m: float = MISSING
    curvature_noise: float = MISSING
    max_speed_mps: float = MISSING
    min_travel_m: float = MISSING
    report: bool = MISSING
    report_dir: Optional[str] = None
    pictures: int = MISSING

    @property
    def reach_m(self) -> float:
        """How far ahead a frame's labels must reach for the frame to be labeled."""
        return self.range_m if self.min_reach_m is None else self.min_reach_m


def validate_autolabel(cfg: AutolabelConfig) -> AutolabelConfig:
    """Check the options; raise :class:`ConfigError` naming the first bad key (``autolabel.*``)."""
    for key in ("range_m", "min_reach_m", "pixel_noise_px", "max_point_std_m", "node_spacing_m", "gate_m", "merge_m",
                "max_std_m", "max_speed_mps", "confirm_hits", "max_misses"):
        check_positive(f"autolabel.{key}", getattr(cfg, key))
    for key in ("min_length_m", "max_gap_m", "process_noise_m", "curvature_noise", "min_travel_m", "pictures", "category_penalty_m"):
        if getattr(cfg, key) < 0:
            raise ConfigError(f"autolabel.{key}={getattr(cfg, key)!r} must be >= 0")
    near_far = list(cfg.projection_range_m)
    if len(near_far) != 2 or not 0 < near_far[0] < near_far[1]:
        raise ConfigError(f"autolabel.projection_range_m={near_far!r} must be [near, far] with 0 < near < far")
    if cfg.min_reach_m is not None and cfg.min_reach_m > cfg.range_m:
        raise ConfigError(f"autolabel.min_reach_m={cfg.min_reach_m!r} is beyond autolabel.range_m={cfg.range_m!r}: "
                          "no frame could be labeled")
    if not 0 <= cfg.min_score <= 1:
        raise ConfigError(f"autolabel.min_score={cfg.min_score!r} must be in [0, 1]")
    return cfg
