"""Collate dataset samples into a batch: stack tensors, keep metadata as lists, pad lanes.

Every tensor of a sample gains a leading batch dimension B (``images`` (B, F, 3, H, W), ...).
The per-lane ground truth (:data:`~lanelab.data.targets.LANE_KEYS`, L rows per sample) is
zero-padded to ``max_lanes`` rows, and ``gt_mask`` (B, max_lanes) bool marks the real lanes.
A fixed lane count keeps batch shapes the same from step to step. Non-tensors (``clip_id``,
``tags``) become lists of length B.
"""

from __future__ import annotations

from typing import Any, Sequence

import torch
from torch.utils.data import default_collate

from lanelab.data.targets import LANE_KEYS


def collate_samples(samples: Sequence[dict[str, Any]], max_lanes: int) -> dict[str, Any]:
    """Samples of :class:`~lanelab.data.dataset.ClipDataset` -> a batch (see the module)."""
    counts = [len(sample["gt_x"]) for sample in samples]
    for sample, count in zip(samples, counts):
        if count > max_lanes:
            raise ValueError(
                f"clip {sample['clip_id']} frame {int(sample['frame_index'][-1])} has {count} lanes, "
                f"more than max_lanes={max_lanes}; raise data.max_lanes"
            )
    batch: dict[str, Any] = {}
    for key, first in samples[0].items():
        values = [sample[key] for sample in samples]
        if key in LANE_KEYS:
            padded = first.new_zeros((len(samples), max_lanes, *first.shape[1:]))
            for row, value in zip(padded, values):
                row[: len(value)] = value
            batch[key] = padded
        elif isinstance(first, torch.Tensor):
            batch[key] = default_collate(values)  # stacks; in a worker, straight into shared memory
        else:
            batch[key] = values
    batch["gt_mask"] = torch.arange(max_lanes) < torch.tensor(counts).unsqueeze(1)
    return batch
