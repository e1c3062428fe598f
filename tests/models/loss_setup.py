"""What the matcher and loss tests build: the settings of conf/model/sparselanestp.yaml, with
DETR's matching on the predictions (the pairs the tests reason about) unless a test says otherwise."""

from __future__ import annotations

from typing import Any

from lanelab.models.parts.matcher import HungarianMatcher

MATCHER: dict[str, Any] = {
    "cost_class": 1.0, "cost_reg": 1.0, "cost_vis": 1.0, "gamma": 2.0, "match_on": "predictions",
    "near_range": 30.0, "max_anchor_distance": None, "positive_distance": None,
}  # fmt: skip
LOSS: dict[str, Any] = {
    "gamma": 2.0, "representation": "catmull_rom", "max_curvature": 0.1, "temporal_alpha": 0.5,
    "temporal_max_distance": 1.0,
}  # fmt: skip


def build_matcher(**options: Any) -> HungarianMatcher:
    """A HungarianMatcher with MATCHER's settings, these replaced."""
    return HungarianMatcher(**{**MATCHER, **options})
