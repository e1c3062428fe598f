"""A tracked line smoothed along its length: a Kalman filter and Rauch-Tung-Striebel smoother in arc length.

The tracker estimates each node of a line on its own; a lane line is smooth, so its nodes
are related. Along the arc length s, the state is the line's lateral offset and its slope,
(d, d'), whose curvature d'' is white noise of density ``curvature_noise``^2 (the continuous
white-noise-acceleration model): a smoothing spline in Kalman form. The forward filter takes
each node's estimate as a measurement of d with its variance, the backward pass (RTS) gives
every node the estimate of all of them, and nodes without a measurement (an occlusion gap)
are interpolated along the line's direction.
"""

from __future__ import annotations

import numpy as np

_INITIAL_SLOPE_VAR = 1.0  # (m/m)^2: the slope is unknown before the first nodes


def smooth_line(s: np.ndarray, d: np.ndarray, var: np.ndarray, curvature_noise: float) -> np.ndarray:
    """Smoothed offsets (M,) at arc lengths s (M,) ascending from measurements d (M,) of variance
    var (M,) (inf: no measurement; the first node must have one)."""
    n = len(s)
    x_f = np.zeros((n, 2))
    P_f = np.zeros((n, 2, 2))
    x_p = np.zeros((n, 2))
    P_p = np.zeros((n, 2, 2))
    x = np.array([d[0], 0.0])
    P = np.diag([var[0], _INITIAL_SLOPE_VAR])
    H = np.array([1.0, 0.0])
    F_all = []
    for k in range(n):
        if k:
            step = s[k] - s[k - 1]
            F = np.array([[1.0, step], [0.0, 1.0]])
            Q = curvature_noise**2 * np.array([[step**3 / 3, step**2 / 2], [step**2 / 2, step]])
            x, P = F @ x, F @ P @ F.T + Q
            F_all.append(F)
        x_p[k], P_p[k] = x, P
        if np.isfinite(var[k]):
            gain = P @ H / (H @ P @ H + var[k])
            x = x + gain * (d[k] - x[0])
            P = P - np.outer(gain, H @ P)
        x_f[k], P_f[k] = x, P
    smoothed = x_f.copy()
    for k in range(n - 2, -1, -1):
        C = P_f[k] @ F_all[k].T @ np.linalg.inv(P_p[k + 1])
        smoothed[k] = x_f[k] + C @ (smoothed[k + 1] - x_p[k + 1])
    return smoothed[:, 0]
