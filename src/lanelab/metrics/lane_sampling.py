"""Lane pruning and resampling at fixed y values, as the official OpenLane evaluator does them.

Source read: OpenDriveLab/OpenLane ``eval/LANE_evaluation/lane3d/utils/utils.py``
(``prune_3d_lane_by_visibility``, ``prune_3d_lane_by_range``, ``resample_laneline_in_y``)
and the lane filters at the top of ``LaneEval.bench`` in ``eval_3D_lane.py``.
"""

from __future__ import annotations

import numpy as np


def overlaps_y_range(lane: np.ndarray, y_first_max: float, y_last_min: float) -> bool:
    """Official "overlaps the sampling range" test on a lane (N, >=2).

    Quirk kept: it reads the lane's first and last points as stored, not its y extent, so a
    lane listed far-to-near must *start* below ``y_first_max`` (the last y sample, 102 m by
    default, not 103 m) and end beyond ``y_last_min`` (the first sample, 3 m).
    """
    return bool(lane[0, 1] < y_first_max and lane[-1, 1] > y_last_min)


def prune_to_box(
    lane: np.ndarray, x_range: tuple[float, float], y_range: tuple[float, float]
) -> np.ndarray:
    """Points of lane (N, >=2) strictly inside the y range, then strictly inside the x range."""
    y, x = lane[:, 1], lane[:, 0]
    keep = (y > y_range[0]) & (y < y_range[1]) & (x > x_range[0]) & (x < x_range[1])
    return lane[keep]


def resample_in_y(
    lane: np.ndarray, y_samples: np.ndarray, x_range: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, z and visibility of a lane (N >= 2, 2 or 3 columns) at y_samples (S,) -> 3 x (S,).

    Linear interpolation in y with linear extrapolation past both ends, computed exactly as
    scipy's ``interp1d(kind="linear", fill_value="extrapolate")`` does it (stable sort by
    y, left-sided search, end segments clipped, ``slope * (y - y_lo) + v_lo``), so the
    numbers are the official ones to the last bit, duplicates and all. Lanes with two columns
    get z = 0.

    A sample is visible when it lies within the lane's y extent and its x within x_range
    (both inclusive). The official ``out_vis`` flag (samples within 5 m of the extent) is
    float ``0/1 + 1e-9`` and therefore never switches a sample off: it is left out.
    """
    order = np.argsort(lane[:, 1], kind="mergesort")
    y = lane[order, 1]
    xz = np.zeros((len(order), 2))
    xz[:, 0] = lane[order, 0]
    if lane.shape[1] > 2:
        xz[:, 1] = lane[order, 2]
    hi = np.clip(np.searchsorted(y, y_samples), 1, len(y) - 1)
    lo = hi - 1
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (xz[hi] - xz[lo]) / (y[hi] - y[lo])[:, None]
        values = slope * (y_samples - y[lo])[:, None] + xz[lo]
    x, z = values[:, 0], values[:, 1]
    visible = (
        (x >= x_range[0]) & (x <= x_range[1]) & (y_samples >= y[0]) & (y_samples <= y[-1])
    )
    return x, z, visible
