"""Draw 3D lanes (lane frame) over a camera image and in a bird's-eye top view.

Used by the synthetic-log preview, and by evaluation and training pictures
(:mod:`lanelab.viz.panels`), so that every picture of lanes in lanelab looks the same. Colours
are BGR (OpenCV's order), pictures (H, W, 3) uint8.

A lane is drawn in its category's colour (:data:`CATEGORY_COLORS`) or, to compare two sets of
lanes in one panel, in one colour per set (``color``: :data:`GT_COLOR` for ground truth,
:data:`PREDICTION_COLOR` for predictions); the parts its labels mark hidden (visibility below
0.5) as thin lines in :data:`HIDDEN_COLOR`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import cv2
import numpy as np
import torch

from lanelab.geometry.camera import project_lane_points
from lanelab.lanes import Lane
from lanelab.viz.text import FONT, text_strip

Color = tuple[int, int, int]

# BGR per OpenLane category id: white lines white-ish, yellow lines yellow, curbs orange.
CATEGORY_COLORS: dict[int, Color] = {
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
HIDDEN_COLOR: Color = (90, 90, 255)
# Ground truth against prediction: green against magenta, opposite hues that differ for
# red-green colour blindness too, and from every category colour.
GT_COLOR: Color = (60, 220, 60)
PREDICTION_COLOR: Color = (230, 40, 230)
VISIBLE = 0.5  # label visibility from which a point is drawn as visible

_GRID, _TICK_TEXT = (55, 55, 55), (170, 170, 170)
AXIS_HEIGHT, TITLE_HEIGHT = 18, 18  # pixels: draw_top_view's x axis and title strips


def category_color(category: int) -> Color:
    """The colour of a category id (unknown ids get category 0's)."""
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


def _draw_lane(
    canvas: np.ndarray, lane: Lane, pixels: np.ndarray, drawable: np.ndarray, thickness: int, show_hidden: bool,
    color: Color | None,
) -> None:  # fmt: skip
    """One lane's pixels (P, 2) where drawable (P,): visible parts thick, hidden ones thin."""
    visible = np.asarray(lane.visibility) >= VISIBLE
    layers = [(visible, color or category_color(lane.category), thickness)]
    if show_hidden:
        layers.insert(0, (~visible, HIDDEN_COLOR, 1))
    for keep, layer_color, width in layers:
        # a hidden point next to a visible one joins both runs, so lines do not break
        # (the full convolution's middle: "same" returns 3 values for a lane of 2 points)
        keep = drawable & (keep | np.convolve(keep, [1, 1, 1])[1:-1].astype(bool))
        for run in _polyline_runs(pixels, keep):
            cv2.polylines(canvas, [run], False, layer_color, width, cv2.LINE_AA, shift=4)


def draw_lanes_on_image(
    image: np.ndarray,
    lanes: Sequence[Lane],
    K: np.ndarray,
    T_lane_cam: np.ndarray,
    thickness: int = 2,
    show_hidden: bool = True,
    color: Color | None = None,
) -> np.ndarray:
    """Return a copy of a BGR image (H, W, 3) with the lanes projected on it.

    Visible points in the category colour (or ``color``); hidden ones (visibility < 0.5) as
    thin :data:`HIDDEN_COLOR` lines when ``show_hidden``. K (3, 3), T_lane_cam (4, 4).
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
        _draw_lane(canvas, lane, uv[start:stop], in_front[start:stop], thickness, show_hidden, color)
        start = stop
    return canvas


@dataclass(frozen=True)
class TopView:
    """A bird's-eye view of the lane frame's region x_range by y_range (metres): x to the
    right, y up the picture, in a picture of size (H, W) whose bottom strip of ``axis_height``
    pixels holds the x axis in metres (0: none).

    :meth:`canvas` gives the empty view (grid every 10 m across, 5 or 50 m on narrow or wide
    ranges, and 50 m along, labelled in metres; the ego at the bottom centre); :meth:`draw` adds
    lanes to one, so that several sets of lanes can share a view.
    """

    size: tuple[int, int]
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    axis_height: int = 14

    def pixels(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Lane-frame x, y (metres, same shape) -> (..., 2) pixel u, v of the plot area."""
        height, width = self.size[0] - self.axis_height, self.size[1]
        u = (x - self.x_range[0]) / (self.x_range[1] - self.x_range[0]) * (width - 1)
        v = (1.0 - (y - self.y_range[0]) / (self.y_range[1] - self.y_range[0])) * (height - 1)
        return np.stack([u, v], -1)

    def canvas(self) -> np.ndarray:
        """The empty view."""
        height, width = self.size
        plot_height = height - self.axis_height
        canvas = np.full((height, width, 3), 30, np.uint8)
        canvas[plot_height:] = 15
        scale = label_scale(self.axis_height)
        # The grid every 10 m (5 m on narrow ranges, 50 m on wide ones); labelled from x = 0
        # outwards, each label where it overlaps none placed before.
        span = self.x_range[1] - self.x_range[0]
        x_step = 5.0 if span < 30 else 10.0 if span < 120 else 50.0
        ticks = np.arange(np.ceil(self.x_range[0] / x_step) * x_step, self.x_range[1] + 1e-6, x_step)
        placed: list[tuple[int, int]] = []
        for x in sorted(ticks, key=abs):
            u = int(round(self.pixels(np.array(x), np.array(self.y_range[0]))[0]))
            cv2.line(canvas, (u, 0), (u, plot_height - 1), _GRID, 1)
            label = f"{x:.0f}m"
            (w, h), _ = cv2.getTextSize(label, FONT, scale, 1)
            left = min(max(u - w // 2, 0), width - w)
            if self.axis_height and all(left + w + 3 <= start or left >= stop + 3 for start, stop in placed):
                cv2.putText(canvas, label, (left, plot_height + (self.axis_height + h) // 2), FONT, scale,
                            _TICK_TEXT, 1, cv2.LINE_AA)  # fmt: skip
                placed.append((left, left + w))
        for y in np.arange(np.ceil(self.y_range[0] / 50) * 50, self.y_range[1] + 1e-6, 50.0):
            v = int(round(self.pixels(np.array(self.x_range[0]), np.array(y))[1]))
            cv2.line(canvas, (0, v), (width - 1, v), _GRID, 1)
            (_, h), _ = cv2.getTextSize("0", FONT, scale, 1)
            cv2.putText(canvas, f"{y:.0f}m", (2, max(v - 2, h + 1)), FONT, scale, _TICK_TEXT, 1, cv2.LINE_AA)
        ego = self.pixels(np.array(0.0), np.array(max(self.y_range[0], 0.0)))
        cv2.circle(canvas, (int(ego[0]), int(min(ego[1], plot_height - 4))), 3, (0, 255, 0), -1)
        return canvas

    def draw(
        self, canvas: np.ndarray, lanes: Sequence[Lane], thickness: int = 2, show_hidden: bool = True,
        color: Color | None = None,
    ) -> np.ndarray:  # fmt: skip
        """canvas (a :meth:`canvas`) with the lanes drawn on it, in place; returned."""
        plot = canvas[: self.size[0] - self.axis_height]  # a view: lanes stay out of the axis strip
        for lane in lanes:
            points = np.asarray(lane.points, np.float64)
            pixels = self.pixels(points[:, 0], points[:, 1])
            _draw_lane(plot, lane, pixels, np.ones(len(points), bool), thickness, show_hidden, color)
        return canvas


def label_scale(strip_height: int) -> float:
    """The font scale of a label in a strip of strip_height pixels: its letters about half as
    tall, and never below 0.3 (smaller Hershey text is unreadable)."""
    return float(np.clip(strip_height / 40, 0.3, 0.5))


def fit_x_range(lanes: Iterable[Lane], y_range: tuple[float, float], least: float = 20.0,
                step: float = 5.0) -> tuple[float, float]:
    """A top view's x range (metres) centred on the ego that holds every point (P, 3) of the
    lanes within y_range, with a metre to spare: (-r, r), r at least ``least``, rounded up to ``step``."""
    reach = least
    for lane in lanes:
        points = np.asarray(lane.points, np.float64)
        inside = (points[:, 1] >= y_range[0]) & (points[:, 1] <= y_range[1])
        if inside.any():
            reach = max(reach, float(np.abs(points[inside, 0]).max()) + 1.0)
    reach = float(np.ceil(reach / step) * step)
    return -reach, reach


def top_view_width(height: int, x_range: tuple[float, float], y_range: tuple[float, float]) -> int:
    """Pixels across a top view of ``height`` pixels: as many as true proportions give, between
    height / 2 (narrow ranges stay readable) and height (wide ones stay a column)."""
    proportional = height * (x_range[1] - x_range[0]) / (y_range[1] - y_range[0])
    return int(np.clip(round(proportional), max(height // 2, 60), max(height, 60)))


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
    """Bird's-eye view (H, W, 3) of lanes in the lane frame (:class:`TopView`), in their
    category colours, hidden parts thin; an optional title in a strip of its own at the top
    (the view below it, so that nothing is drawn over the title)."""
    title_height = TITLE_HEIGHT if title else 0
    view = TopView((size[0] - title_height, size[1]), x_range, y_range, axis_height=AXIS_HEIGHT)
    canvas = view.draw(view.canvas(), lanes)
    if not title:
        return canvas
    return np.vstack([text_strip([(title, size[1])], title_height), canvas])
