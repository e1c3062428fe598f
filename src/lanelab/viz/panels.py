"""Pictures that compare ground truth with predictions, frame by frame, with a legend.

One row per frame (:func:`comparison_row`), under a title strip (the frame, and the training
step where there is one) and a strip of panel captions::

    ground truth        | prediction          | GT vs prediction    | top view
    (category colours)  | (category colours)  | (green vs magenta)  | (green vs magenta; x, y in m)

The first two panels show each set in its categories' colours, hidden parts thin red; the last
two draw both sets in one panel, ground truth thick green under prediction thin magenta, their
visible parts only (what the metric scores), so that misses, false lanes and offsets show.
:func:`legend` explains the colours (the categories drawn, hidden parts, GT and prediction) and
:func:`stack_rows` puts rows and legend together. Text is sized to fit its strip and width,
and shortened with ".." rather than cut or overlapping. Colours are BGR.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import cv2
import numpy as np

from lanelab.lanes import LANE_CATEGORY_NAMES, Lane
from lanelab.viz.lanes import (
    GT_COLOR,
    Color,
    HIDDEN_COLOR,
    PREDICTION_COLOR,
    TopView,
    category_color,
    draw_lanes_on_image,
)
from lanelab.viz.text import FONT, SMALLEST_SCALE, STRIP_COLOR, TEXT_COLOR, text_strip

PANEL_CAPTIONS = ("ground truth", "prediction", "GT vs prediction", "top view")


def strip_height(height: int) -> int:
    """Pixels of a text strip over a row of panels of `height` pixels."""
    return int(np.clip(round(height * 0.06), 12, 22))


def comparison_row(
    image: np.ndarray,
    K: np.ndarray,
    T_lane_cam: np.ndarray,
    gt: Sequence[Lane],
    pred: Sequence[Lane],
    height: int,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    title: str,
) -> np.ndarray:
    """One frame's row (strips + height, W, 3) BGR: the four panels of the module under its
    title and captions. image (h, w, 3) BGR is scaled to height pixels; K (3, 3) is its
    intrinsics, T_lane_cam (4, 4); lanes in the lane frame; x_range, y_range (metres): the
    region of the top view, which is height / 2 pixels wide."""
    scale = height / image.shape[0]
    image = cv2.resize(image, (round(image.shape[1] * scale), height),
                       interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)  # fmt: skip
    # Pixel coordinates are continuous with pixel edges at integers, so scaling them is exact.
    K = np.diag([scale, scale, 1.0]) @ K
    thick = max(2, height // 120)
    # Ground truth as a wide band, the prediction as a line inside it where they agree.
    wide, narrow = 2 * thick + 3, thick
    both = draw_lanes_on_image(image, gt, K, T_lane_cam, thickness=wide, show_hidden=False, color=GT_COLOR)
    both = draw_lanes_on_image(both, pred, K, T_lane_cam, thickness=narrow, show_hidden=False, color=PREDICTION_COLOR)
    view = TopView((height, max(height // 2, 60)), x_range, y_range, axis_height=strip_height(height))
    top_wide = max(3, view.size[1] // 30)  # lanes a few metres apart stay apart in a narrow view
    top = view.draw(view.canvas(), gt, thickness=top_wide, show_hidden=False, color=GT_COLOR)
    top = view.draw(top, pred, thickness=max(1, top_wide // 2), show_hidden=False, color=PREDICTION_COLOR)
    panels = [
        draw_lanes_on_image(image, gt, K, T_lane_cam, thickness=thick),
        draw_lanes_on_image(image, pred, K, T_lane_cam, thickness=thick),
        both,
        top,
    ]
    widths = [panel.shape[1] for panel in panels]
    strip = strip_height(height)
    return np.vstack([
        text_strip([(title, sum(widths))], strip),
        text_strip(list(zip(PANEL_CAPTIONS, widths)), strip),
        np.hstack(panels),
    ])  # fmt: skip


# What a picture draws in a colour of its own, beside the categories: name -> (colour, line width).
KINDS: dict[str, tuple[Color, int]] = {
    "ground truth": (GT_COLOR, 4), "prediction": (PREDICTION_COLOR, 2), "hidden part": (HIDDEN_COLOR, 1),
}  # fmt: skip


def legend(width: int, categories: Iterable[int], height: int, kinds: Sequence[str] = tuple(KINDS)) -> np.ndarray:
    """A legend strip (h, width, 3), wrapped into as many lines as it needs: the colours of
    `kinds` (of :data:`KINDS`: ground truth, prediction, the hidden-part line), then each category
    of `categories` (its colour and OpenLane name). height: the row height it goes under (sizes the text)."""
    line_height = strip_height(height) + 4
    scale = max((line_height - 10) / 30, SMALLEST_SCALE)
    entries: list[tuple[str, Color, int]] = [(kind, *KINDS[kind]) for kind in kinds]  # name, colour, line width
    entries += [(LANE_CATEGORY_NAMES.get(c, f"category {c}"), category_color(c), 3) for c in sorted(set(categories))]
    swatch = 2 * line_height
    lines: list[list[tuple[int, tuple[str, Color, int]]]] = [[]]  # per line: (left, entry)
    left = 4
    for entry in entries:
        entry_width = swatch + 6 + cv2.getTextSize(entry[0], FONT, scale, 1)[0][0] + 14
        if left + entry_width > width and lines[-1]:
            lines.append([])
            left = 4
        lines[-1].append((left, entry))
        left += entry_width
    canvas = np.full((line_height * len(lines) + 4, width, 3), STRIP_COLOR, np.uint8)
    for row, line in enumerate(lines):
        middle = 2 + row * line_height + line_height // 2
        for left, (name, color, thickness) in line:
            cv2.line(canvas, (left, middle), (left + swatch, middle), color, thickness)  # horizontal: no anti-aliasing
            cv2.putText(canvas, name, (left + swatch + 6, middle + round(8 * scale)), FONT, scale, TEXT_COLOR, 1,
                        cv2.LINE_AA)  # fmt: skip
    return canvas


def stack_rows(rows: Sequence[np.ndarray], categories: Iterable[int], height: int,
               kinds: Sequence[str] = tuple(KINDS)) -> np.ndarray:
    """Rows (h_i, w_i, 3) stacked, narrower ones padded black on the right, over the legend of
    `kinds` and `categories` (see :func:`legend`; height: the rows' panel height)."""
    width = max(row.shape[1] for row in rows)
    padded = [np.pad(row, ((0, 0), (0, width - row.shape[1]), (0, 0))) for row in rows]
    return np.vstack([*padded, legend(width, categories, height, kinds)])


def categories_of(*lane_sets: Iterable[Lane]) -> set[int]:
    """The category ids of the lanes of every set."""
    return {int(lane.category) for lanes in lane_sets for lane in lanes}
