"""Checking a calibration where it enters: is K a pinhole camera matrix?

Every projection in lanelab (:mod:`lanelab.geometry.camera`) takes K as
``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with positive focal lengths. Any other K (a zero
``K[2][2]``, a lower-triangular entry, a focal length of 0) projects points nowhere or
everywhere without an error, so readers of drive logs and datasets refuse it first.
"""

from __future__ import annotations

import numpy as np

TOLERANCE = 1e-9  # on the entries that must be 0 or 1 (values from text formats round-trip exactly)


def pinhole_problem(K: np.ndarray) -> str:
    """What keeps K (3, 3) from being a pinhole camera matrix with positive focal lengths: "" if nothing."""
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        return f"has shape {K.shape}, not (3, 3)"
    if not np.isfinite(K).all():
        return "holds NaN or inf"
    if not (K[0, 0] > 0 and K[1, 1] > 0):
        return f"focal lengths fx={K[0, 0]:g}, fy={K[1, 1]:g} are not both positive"
    if np.abs(K[2] - (0, 0, 1)).max() > TOLERANCE:
        return f"last row is {K[2].tolist()}, not [0, 0, 1]"
    if abs(K[1, 0]) > TOLERANCE:
        return f"K[1][0]={K[1, 0]:g}, not 0 (not upper-triangular)"
    return ""
