"""The OpenLane metric as a torchmetrics ``Metric``, fed with lane tensors during validation.

Each frame goes through the same :func:`~lanelab.metrics.openlane.evaluate_frame` as the
file-based evaluator, and the states are sums (counts, sums of per-pair errors and their
numbers), reduced with ``"sum"`` across processes. Under DDP, recall and precision are
therefore computed from the counts of all ranks and every error mean is over all matched
pairs of all ranks -- never an average of per-rank averages -- so a run on N ranks gives
the single-process numbers (up to the order of floating-point additions in the error sums).

Frames: predictions and ground truth must be in one common frame, the lane frame (x right,
y forward, z up); no extrinsic conversion happens here. lanelab's lane frame has its origin
on the ground under ``base_link`` (DESIGN.md), whereas the official evaluator converts
OpenLane's GT into a ground frame whose origin lies under the *camera*
(:func:`~lanelab.openlane.ground_frame.ground_from_camera`). The y-sampling (3 .. 102 m) and
the |x| < 10 m box are measured from the origin, so the numbers are the official ones for
GT converted the official way, and lanelab-frame numbers for lanelab's own clips.

Usage in a LightningModule::

    self.val_metric = OpenLaneMetric()
    ...
    self.val_metric.update(predicted_lanes, gt_lanes)        # in validation_step
    self.log_dict(self.val_metric.compute()); self.val_metric.reset()  # at epoch end
"""

from __future__ import annotations

from typing import Any, NamedTuple, Sequence

import numpy as np
import torch
from torchmetrics import Metric

from lanelab.metrics.openlane import (
    COUNT_KEYS,
    FrameResult,
    OpenLaneConfig,
    detection_scores,
    evaluate_frame,
)


class LaneBatch(NamedTuple):
    """Dense 3D lanes of B frames, L lane slots per frame, K points per lane, in the lane
    frame (metres).

    points: (B, L, K, 3) x right, y forward, z up. Lanes with fewer than K points are padded
        with non-finite (NaN) points, which are dropped.
    visibility: (B, L, K) in [0, 1]. Ground truth: points with visibility <= 0 are dropped
        (the official rule). Predictions: points at or below config.visibility_threshold are
        dropped, as lanelab's OpenLane writer leaves them out of prediction files.
    category: (B, L) integer OpenLane category ids (for predictions, the argmax class).
    valid: (B, L) bool, which slots hold a lane (predictions: those kept after scoring).
    """

    points: torch.Tensor
    visibility: torch.Tensor
    category: torch.Tensor
    valid: torch.Tensor

    @classmethod
    def from_lists(
        cls,
        lanes: Sequence[Sequence[np.ndarray]],
        visibility: Sequence[Sequence[np.ndarray]],
        categories: Sequence[Sequence[int]],
        slots: int | None = None,
    ) -> LaneBatch:
        """Pack B frames of ragged lanes: lanes[b][i] (N_bi, 3), visibility[b][i] (N_bi,),
        categories[b][i]; into `slots` lane slots (default: the most lanes of a frame) of
        as many points as the longest lane, NaN-padded (float64)."""
        B = len(lanes)
        slots = max([len(frame) for frame in lanes] + [0]) if slots is None else slots
        K = max([len(lane) for frame in lanes for lane in frame] + [0])
        batch = cls(
            points=torch.full((B, slots, K, 3), float("nan"), dtype=torch.float64),
            visibility=torch.zeros((B, slots, K), dtype=torch.float64),
            category=torch.zeros((B, slots), dtype=torch.int64),
            valid=torch.zeros((B, slots), dtype=torch.bool),
        )
        for b in range(B):
            for i, (lane, vis) in enumerate(zip(lanes[b], visibility[b], strict=True)):
                batch.points[b, i, : len(lane)] = torch.as_tensor(np.asarray(lane, np.float64))
                batch.visibility[b, i, : len(lane)] = torch.as_tensor(np.asarray(vis, np.float64))
                batch.category[b, i] = int(categories[b][i])
                batch.valid[b, i] = True
        return batch


class OpenLaneMetric(Metric):
    """OpenLane F1, recall, precision, category accuracy, x/z errors (and the extensions the
    config turns on: further error ranges, Vis-IoU), accumulated over batches and ranks.

    compute() returns float64 scalar tensors under the keys of
    :func:`~lanelab.metrics.openlane.summarize`: the scores, one mean per pair value
    (NaN when no pair has one), num_frames and the counts.
    """

    is_differentiable = False
    higher_is_better = True
    full_state_update = False

    def __init__(self, config: OpenLaneConfig = OpenLaneConfig(), **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.config = config
        count, total = torch.tensor(0, dtype=torch.int64), torch.tensor(0.0, dtype=torch.float64)
        for key in ("num_frames", *COUNT_KEYS):
            self.add_state(key, default=count.clone(), dist_reduce_fx="sum")
        for name in config.pair_value_names:
            self.add_state(f"{name}_sum", default=total.clone(), dist_reduce_fx="sum")
            self.add_state(f"{name}_count", default=count.clone(), dist_reduce_fx="sum")

    def update(self, preds: LaneBatch, target: LaneBatch) -> None:
        """Score the B frames of a batch: preds and target are LaneBatch of the same B."""
        frames = [
            evaluate_frame(
                gt.lanes, gt.visibility, gt.categories, pred.lanes, pred.categories,
                self.config, pred_visibility=pred.visibility,
            )
            for pred, gt in zip(_frames(preds), _frames(target), strict=True)
        ]
        self._add(frames)

    def _add(self, frames: list[FrameResult]) -> None:
        """Add frame results to the states (summed in Python first: one tensor op a state)."""
        increments: dict[str, int | float] = {"num_frames": len(frames)}
        for key in COUNT_KEYS:
            increments[key] = sum(f.counts[key] for f in frames)
        for name in self.config.pair_value_names:
            values = np.concatenate([f.pair_values[name] for f in frames] or [np.zeros(0)])
            values = values[~np.isnan(values)]
            increments[f"{name}_sum"] = float(values.sum())
            increments[f"{name}_count"] = len(values)
        for state, amount in increments.items():
            setattr(self, state, getattr(self, state) + amount)

    def compute(self) -> dict[str, torch.Tensor]:
        counts = {key: int(getattr(self, key)) for key in COUNT_KEYS}
        result: dict[str, float] = dict(detection_scores(counts))
        for name in self.config.pair_value_names:
            count = int(getattr(self, f"{name}_count"))
            total = float(getattr(self, f"{name}_sum"))
            result[name] = total / count if count else float("nan")
        result["num_frames"] = int(self.num_frames)
        result.update(counts)
        return {key: torch.tensor(value, dtype=torch.float64) for key, value in result.items()}


class _FrameLanes(NamedTuple):
    """One frame of a LaneBatch as evaluate_frame takes it: lanes[i] (N_i, 3) float64,
    visibility[i] (N_i,), categories[i] int."""

    lanes: list[np.ndarray]
    visibility: list[np.ndarray]
    categories: list[int]


def _frames(batch: LaneBatch) -> list[_FrameLanes]:
    """The valid lanes of each frame of a batch, padding points removed."""
    points = batch.points.detach().to("cpu", torch.float64).numpy()
    visibility = batch.visibility.detach().to("cpu", torch.float64).numpy()
    category = batch.category.detach().cpu().numpy()
    valid = batch.valid.detach().cpu().numpy().astype(bool)
    frames = []
    for b in range(points.shape[0]):
        slots = np.flatnonzero(valid[b])
        real = [np.isfinite(points[b, i]).all(axis=-1) for i in slots]
        frames.append(
            _FrameLanes(
                lanes=[points[b, i][keep] for i, keep in zip(slots, real)],
                visibility=[visibility[b, i][keep] for i, keep in zip(slots, real)],
                categories=[int(c) for c in category[b, slots]],
            )
        )
    return frames
