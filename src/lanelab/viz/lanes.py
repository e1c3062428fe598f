"""Draw 3D lanes (lane frame) over a camera image and in a bird's-eye top view.

Used by the synthetic-log preview, and by evaluation and training pictures, so that
every picture of lanes in lanelab looks the same.
"""

from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np
import torch

from lanelab.geometry.camera import project_lane_points
from lanelab.lanes import Lane

# BGR per OpenLane category id: white lines white-ish, yellow lines yellow, curbs orange.
CATEGORY_COLORS: dict[int, tuple[int, int, int]] = {
    0: (200, 200, 200),
    1: (255, 255, 255),
    2: (235, 235, 255),
    3: (255, 230, 230),
    4: (255, 210, 210),
    5: (230, 255, 230),
    6: (210, 255, 210),
    7: (0, 230, 255),
    8: (0, 200, 255),
    9: (40, 255, 255),
    10: (0, 170, 255),
    11: (60, 220, 230),
    12: (60, 190, 230),
    20: (0, 110, 255),
    21: (255, 110, 0),
}
HIDDEN_COLOR = (90, 90, 255)


def _color(category: int) -> tuple[int, int, int]:
    return CATEGORY_COLORS.get(int(category), CATEGORY_COLORS[0])


def _polyline_runs(pixels: np.ndarray, keep: np.ndarray) -> list[np.ndarray]:
    """Split (P, 2) pixels into runs of consecutive kept points, for cv2.polylines."""
    runs, start = [], None
    for i, k in enumerate(np.append(keep, False)):
        if k and start is None:
            start = i
        elif not k and start is not None:
            if i - start >= 2:
                runs.append(np.round(pixels[start:i] * 16).astype(np.int32))
            start = None
    return runs


def draw_lanes_on_image(
    image: np.ndarray,
    lanes: Sequence[Lane],
    K: np.ndarray,
    T_lane_cam: np.ndarray,
    thickness: int = 2,
    show_hidden: bool = True,
) -> np.ndarray:
    """Return a copy of a BGR image (H, W, 3) with the lanes projected on it.

    Visible points are drawn in the category colour; hidden ones (visibility < 0.5)
    as thin red lines when ``show_hidden``. K (3, 3), T_lane_cam (4, 4).
    """
    canvas = image.copy()
    if not lanes:
        return canvas
    points = torch.from_numpy(np.concatenate([np.asarray(l.points, np.float64) for l in lanes]))
    uv, _, in_front = project_lane_points(
        points, torch.as_tensor(K, dtype=torch.float64), torch.as_tensor(T_lane_cam, dtype=torch.float64)
    )
    uv, in_front = uv.numpy(), in_front.numpy()
    start = 0
    for lane in lanes:
        stop = start + len(lane.points)
        pixels, front = uv[start:stop], in_front[start:stop]
        visible = np.asarray(lane.visibility) >= 0.5
        layers = [(visible, _color(lane.category), thickness)]
        if show_hidden:
            layers.insert(0, (~visible, HIDDEN_COLOR, 1))
        for keep, color, width in layers:
            # a hidden point next to a visible one joins both runs, so lines do not break
            keep = front & (keep | np.convolve(keep, [1, 1, 1], "same").astype(bool))
            for run in _polyline_runs(pixels, keep):
                cv2.polylines(canvas, [run], False, color, width, cv2.LINE_AA, shift=4)
        start = stop
    return canvas


def draw_polylines(
    image: np.ndarray,
    polylines: Sequence[np.ndarray],
    colors: Sequence[tuple[int, int, int]],
    thickness: int = 2,
) -> np.ndarray:
    """Return a copy of a BGR image (H, W, 3) with 2D polylines (P, 2) in pixels (the pixel-edge
    convention of lanelab.geometry.camera) drawn in their BGR colours."""
    canvas = image.copy()
    for line, color in zip(polylines, colors):
        if len(line) >= 2:
            # Pixel centres sit at half-integers; OpenCV draws at integer pixel indices.
            run = np.round((np.asarray(line, np.float64) - 0.5) * 16).astype(np.int32)
            cv2.polylines(canvas, [run], False, color, thickness, cv2.LINE_AA, shift=4)
    return canvas


def draw_top_view(
    lanes: Sequence[Lane],
    size: tuple[int, int] = (400, 200),
    x_range: tuple[float, float] = (-20.0, 20.0),
    y_range: tuple[float, float] = (0.0, 200.0),
    title: str | None = None,
) -> np.ndarray:
    """Bird's-eye view (H, W, 3) of lanes in the lane frame: x to the right, y up the picture.

    Visible parts in the category colour, hidden parts thin red; a grid every 10 m
    across and 50 m along; the ego at the bottom centre.
    """
    height, width = size
    canvas = np.full((height, width, 3), 30, np.uint8)

    def to_pixels(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        u = (x - x_range[0]) / (x_range[1] - x_range[0]) * (width - 1)
        v = (1.0 - (y - y_range[0]) / (y_range[1] - y_range[0])) * (height - 1)
        return np.stack([u, v], -1)

    for x in np.arange(np.ceil(x_range[0] / 10) * 10, x_range[1] + 1e-6, 10.0):
        u = int(round(to_pixels(np.array(x), np.array(y_range[0]))[0]))
        cv2.line(canvas, (u, 0), (u, height - 1), (55, 55, 55), 1)
    for y in np.arange(np.ceil(y_range[0] / 50) * 50, y_range[1] + 1e-6, 50.0):
        v = int(round(to_pixels(np.array(x_range[0]), np.array(y))[1]))
        cv2.line(canvas, (0, v), (width - 1, v), (55, 55, 55), 1)
        cv2.putText(canvas, f"{y:.0f}m", (2, max(v - 2, 10)), cv2.FONT_HERSHEY_SIMPLEX, 0.3, (120, 120, 120), 1)
    for lane in lanes:
        points = np.asarray(lane.points, np.float64)
        pixels = to_pixels(points[:, 0], points[:, 1])
        visible = np.asarray(lane.visibility) >= 0.5
        for keep, color, w in ((np.ones_like(visible), HIDDEN_COLOR, 1), (visible, _color(lane.category), 2)):
            for run in _polyline_runs(pixels, keep):
                cv2.polylines(canvas, [run], False, color, w, cv2.LINE_AA, shift=4)
    ego = to_pixels(np.array(0.0), np.array(max(y_range[0], 0.0)))
    cv2.circle(canvas, (int(ego[0]), int(min(ego[1], height - 4))), 3, (0, 255, 0), -1)
    if title:
        cv2.putText(canvas, title, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return canvas
