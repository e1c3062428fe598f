"""Comparison rows: ground truth and prediction in their own colours where each lies, a legend
of every colour drawn, titles that fit; training pictures show both with the frame and step."""

import cv2
import numpy as np
import pytest
import torch
from test_lanes import T_LANE_CAM, pixel_of, straight_lane

from lanelab.lightning.pictures import prediction_picture
from lanelab.viz import CATEGORY_COLORS, GT_COLOR, PREDICTION_COLOR
from lanelab.viz.lanes import HIDDEN_COLOR, TopView
from lanelab.viz.panels import comparison_row, legend, stack_rows, strip_height
from lanelab.viz.text import fit_text

HEIGHT = 480  # the test camera's own size: no scaling, so pixel_of() holds in every camera panel
K = np.array([[400.0, 0, 320], [0, 400, 240], [0, 0, 1]])
X_RANGE, Y_RANGE = (-15.0, 15.0), (0.0, 100.0)


def color_mask(picture: np.ndarray, color) -> np.ndarray:
    return np.all(picture == color, axis=-1)


@pytest.fixture(scope="module")
def row() -> np.ndarray:
    """GT: a yellow solid at x = -1.8 m (hidden beyond 20 m) and a right curb at 3.6 m, which the
    prediction misses; prediction: the yellow line 1 m off, at x = -0.8 m."""
    gt = [straight_lane(-1.8, 8, visible_until=20.0), straight_lane(3.6, 21)]
    pred = [straight_lane(-0.8, 8)]
    return comparison_row(np.zeros((480, 640, 3), np.uint8), K, T_LANE_CAM, gt, pred, HEIGHT, X_RANGE, Y_RANGE,
                          "clip-a frame 7, step 120")  # fmt: skip


def panels(row: np.ndarray) -> list[np.ndarray]:
    body = row[2 * strip_height(HEIGHT) :]
    assert body.shape[0] == HEIGHT
    return [body[:, :640], body[:, 640:1280], body[:, 1280:1920], body[:, 1920:]]


def test_gt_and_prediction_are_drawn_apart_in_category_colours(row: np.ndarray) -> None:
    gt, pred, _, _ = panels(row)
    u, v = pixel_of([-1.8, 10.0, 0.0])
    assert tuple(gt[v, u]) == CATEGORY_COLORS[8] and not gt[pixel_of([-0.8, 10.0, 0.0])[::-1]].any()
    u, v = pixel_of([3.6, 10.0, 0.0])
    assert tuple(gt[v, u]) == CATEGORY_COLORS[21] and not pred[v, u].any()
    u, v = pixel_of([-0.8, 10.0, 0.0])
    assert tuple(pred[v, u]) == CATEGORY_COLORS[8]
    assert np.abs(gt[pixel_of([-1.8, 40.0, 0.0])[::-1]].astype(int) - HIDDEN_COLOR).sum() < 80  # hidden: thin red


def test_one_panel_shows_gt_and_prediction_in_contrasting_colours_where_each_lies(row: np.ndarray) -> None:
    _, _, both, top = panels(row)
    for x, color in ((-1.8, GT_COLOR), (3.6, GT_COLOR), (-0.8, PREDICTION_COLOR)):
        u, v = pixel_of([x, 10.0, 0.0])
        assert tuple(both[v, u]) == color, x
    assert not color_mask(both, HIDDEN_COLOR).any()  # visible parts only, as scored
    view = TopView((HEIGHT, HEIGHT // 2), X_RANGE, Y_RANGE, axis_height=strip_height(HEIGHT))
    for x, color in ((-1.8, GT_COLOR), (3.6, GT_COLOR), (-0.8, PREDICTION_COLOR)):
        u, v = np.round(view.pixels(np.array(x), np.array(10.0))).astype(int)
        assert tuple(top[v, u]) == color, x
    assert color_mask(top, GT_COLOR).sum() > color_mask(top, PREDICTION_COLOR).sum()  # GT the wider band


def test_the_legend_shows_every_colour_drawn() -> None:
    strip = legend(900, [8, 21], HEIGHT)
    for color in (GT_COLOR, PREDICTION_COLOR, HIDDEN_COLOR, CATEGORY_COLORS[8], CATEGORY_COLORS[21]):
        assert color_mask(strip, color).any(), color
    assert not color_mask(strip, CATEGORY_COLORS[20]).any()  # only the categories drawn
    narrow = legend(200, [8, 21], HEIGHT)
    assert narrow.shape[0] > strip.shape[0]  # wrapped into more lines, not cut
    for color in (GT_COLOR, CATEGORY_COLORS[21]):
        assert color_mask(narrow, color).any()
    picture = stack_rows([np.zeros((10, 300, 3), np.uint8), np.zeros((10, 200, 3), np.uint8)], [8], HEIGHT)
    assert picture.shape[1] == 300 and color_mask(picture[20:], CATEGORY_COLORS[8]).any()


@pytest.mark.parametrize("width, height", [(120, 12), (400, 22), (60, 16)])
def test_titles_fit_their_strip(width: int, height: int) -> None:
    title = "segment-10203656353524179475_7625_000_7645_000_with_camera_labels/155840113564752100"
    text, scale = fit_text(title, width, height)
    (w, h), baseline = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    assert w <= width - 6 and h + baseline <= height
    assert text == title or ".." in text
    assert text.startswith(title[:2]) and text.endswith(title[-1])  # both ends of the name kept
    assert fit_text("step 7", 400, 22)[0] == "step 7"


def test_a_training_picture_shows_gt_and_prediction_with_frame_and_step() -> None:
    image = torch.zeros(3, 48, 64)
    K_small = torch.tensor([[40.0, 0, 32], [0, 40, 24], [0, 0, 1]])
    gt, pred = [straight_lane(-1.8, 8)], [straight_lane(-0.8, 8)]
    picture = prediction_picture(image, K_small, torch.tensor(T_LANE_CAM), pred, gt, X_RANGE, Y_RANGE, 96,
                                 "clip-a frame 7, step 120")[..., ::-1]  # RGB -> BGR  # fmt: skip
    strip = strip_height(96)
    assert picture[: 2 * strip].max() > 200  # title and captions written
    body = picture[2 * strip : 2 * strip + 96]
    assert color_mask(body, GT_COLOR).any() and color_mask(body, PREDICTION_COLOR).any()
    legend_part = picture[2 * strip + 96 :]
    assert color_mask(legend_part, GT_COLOR).any() and color_mask(legend_part, CATEGORY_COLORS[8]).any()
