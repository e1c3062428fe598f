"""Lane categories as every detector classifies them: the K OpenLane categories
(:data:`lanelab.lanes.LANE_CATEGORY_IDS`) in the order of the classifier's outputs, then the
background, at index K."""

from __future__ import annotations

import torch
from torch import Tensor

from lanelab.lanes import LANE_CATEGORY_IDS

NUM_LANE_CATEGORIES = len(LANE_CATEGORY_IDS)
BACKGROUND_INDEX = NUM_LANE_CATEGORIES


def category_to_index(category_ids: Tensor) -> Tensor:
    """OpenLane category ids (any shape) -> classifier indices 0..K-1; unknown ids raise."""
    table = torch.full((max(LANE_CATEGORY_IDS) + 1,), -1, dtype=torch.long, device=category_ids.device)
    table[list(LANE_CATEGORY_IDS)] = torch.arange(NUM_LANE_CATEGORIES, device=category_ids.device)
    index = table[category_ids.long().clamp(0, len(table) - 1)]
    if bool(((index < 0) | (category_ids < 0) | (category_ids >= len(table))).any()):
        raise ValueError(f"category ids must be in {LANE_CATEGORY_IDS}")
    return index


def index_to_category(index: Tensor) -> Tensor:
    """Classifier indices 0..K-1 (any shape) -> OpenLane category ids."""
    return torch.tensor(LANE_CATEGORY_IDS, device=index.device)[index]
