"""Line charts drawn with OpenCV, without matplotlib's import cost: learning curves and the like.

``line_chart`` draws one panel (several series against a shared x axis, an optional dashed
reference level); ``chart_grid`` tiles panels into one picture.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

# Colours are RGB: pictures are RGB uint8, like the rest of lanelab.viz.
_PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
            (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))  # fmt: skip
_BLACK, _GRID = (0, 0, 0), (220, 220, 220)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def line_chart(
    title: str,
    series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    x_label: str = "step",
    reference: tuple[str, float] | None = None,
    size: tuple[int, int] = (300, 420),
) -> np.ndarray:
    """One panel (H, W, 3) RGB uint8 of size (H, W): each series label -> (x, y) as a polyline
    (non-finite y are skipped), a legend, and reference = (label, level) as a dashed line."""
    height, width = size
    left, right, top, bottom = 55, 10, 28, 36
    canvas = np.full((height, width, 3), 255, np.uint8)
    points = [(x, y) for xs, ys in series.values() for x, y in zip(xs, ys) if math.isfinite(y)]
    levels = [y for _, y in points] + ([reference[1]] if reference and math.isfinite(reference[1]) else [])
    x_values = [x for x, _ in points] or [0.0, 1.0]
    x_low, x_high = min(x_values), max(x_values)
    y_low, y_high = (min(levels), max(levels)) if levels else (0.0, 1.0)
    x_high, y_high = max(x_high, x_low + 1e-9), max(y_high, y_low + 1e-9)
    pad = 0.05 * (y_high - y_low)
    y_low, y_high = y_low - pad, y_high + pad

    def pixel(x: float, y: float) -> tuple[int, int]:
        u = left + (x - x_low) / (x_high - x_low) * (width - left - right)
        v = height - bottom - (y - y_low) / (y_high - y_low) * (height - top - bottom)
        return round(u), round(v)

    for level in np.linspace(y_low, y_high, 5):
        _, v = pixel(x_low, level)
        cv2.line(canvas, (left, v), (width - right, v), _GRID, 1)
        cv2.putText(canvas, f"{level:.3g}", (2, v + 4), _FONT, 0.35, _BLACK, 1, cv2.LINE_AA)
    for x in np.linspace(x_low, x_high, 4):
        u, _ = pixel(x, y_low)
        cv2.putText(canvas, f"{x:.4g}", (u - 12, height - bottom + 14), _FONT, 0.35, _BLACK, 1, cv2.LINE_AA)
    cv2.putText(canvas, x_label, (width // 2 - 15, height - 6), _FONT, 0.4, _BLACK, 1, cv2.LINE_AA)
    cv2.putText(canvas, title, (left, 18), _FONT, 0.45, _BLACK, 1, cv2.LINE_AA)
    if reference is not None and math.isfinite(reference[1]):
        _, v = pixel(x_low, reference[1])
        for u in range(left, width - right, 10):
            cv2.line(canvas, (u, v), (min(u + 5, width - right), v), (90, 90, 90), 1)
        cv2.putText(canvas, reference[0], (width - right - 90, v - 4), _FONT, 0.35, (90, 90, 90), 1, cv2.LINE_AA)
    for index, (label, (xs, ys)) in enumerate(series.items()):
        color = _PALETTE[index % len(_PALETTE)]
        line = [pixel(x, y) for x, y in zip(xs, ys) if math.isfinite(y)]
        if len(line) > 1:
            cv2.polylines(canvas, [np.array(line, np.int32)], False, color, 1, cv2.LINE_AA)
        for point in line if len(line) < 30 else ():
            cv2.circle(canvas, point, 2, color, -1, cv2.LINE_AA)
        cv2.putText(canvas, label, (left + 5, top + 12 + 12 * index), _FONT, 0.35, color, 1, cv2.LINE_AA)
    return canvas


def chart_grid(panels: Sequence[np.ndarray], columns: int) -> np.ndarray:
    """Tile equally sized panels (H, W, 3) row by row, ``columns`` per row (blank fill)."""
    height, width = panels[0].shape[:2]
    rows = math.ceil(len(panels) / columns)
    grid = np.full((rows * height, columns * width, 3), 255, np.uint8)
    for index, panel in enumerate(panels):
        row, column = divmod(index, columns)
        grid[row * height : (row + 1) * height, column * width : (column + 1) * width] = panel
    return grid
