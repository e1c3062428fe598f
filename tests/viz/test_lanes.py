"""Lane pictures put the lanes where the camera model says, in their category colour."""

import numpy as np
import torch

from lanelab.geometry.camera import project_lane_points
from lanelab.lanes import Lane
from lanelab.viz import CATEGORY_COLORS, draw_lanes_on_image, draw_top_view
from lanelab.viz.lanes import HIDDEN_COLOR, TopView

K = np.array([[400.0, 0, 320], [0, 400, 240], [0, 0, 1]])
# camera 1.5 m above the lane-frame origin, looking along +y (lane frame: x right, y forward, z up)
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])


def straight_lane(x: float, category: int, visible_until: float = 100.0) -> Lane:
    y = np.linspace(3, 60, 80)
    points = np.stack([np.full_like(y, x), y, np.zeros_like(y)], -1)
    return Lane(points, (y <= visible_until).astype(np.float32), category)


def pixel_of(point) -> tuple[int, int]:
    uv, _, _ = project_lane_points(torch.tensor([point], dtype=torch.float64), torch.tensor(K), torch.tensor(T_LANE_CAM))
    u, v = uv[0].round().long().tolist()
    return u, v


def test_overlay_draws_visible_lanes_in_category_colour_and_hidden_parts_red():
    image = np.zeros((480, 640, 3), np.uint8)
    lanes = [straight_lane(-1.8, 8, visible_until=20.0), straight_lane(1.8, 21)]
    out = draw_lanes_on_image(image, lanes, K, T_LANE_CAM, thickness=3)
    assert not image.any(), "the input image must not be modified"
    u, v = pixel_of([1.8, 10.0, 0.0])
    assert tuple(out[v, u]) == CATEGORY_COLORS[21]
    u, v = pixel_of([-1.8, 10.0, 0.0])
    assert tuple(out[v, u]) == CATEGORY_COLORS[8]
    u, v = pixel_of([-1.8, 40.0, 0.0])  # past visible_until: a thin anti-aliased line in the hidden colour
    patch = out[v - 1 : v + 2, u - 1 : u + 2].reshape(-1, 3).astype(int)
    assert np.abs(patch - HIDDEN_COLOR).sum(-1).min() < 80
    assert not (patch == CATEGORY_COLORS[8]).all(-1).any()
    u, v = pixel_of([0.0, 10.0, 0.0])  # between the lanes nothing is drawn
    assert not out[v, u].any()


def test_points_behind_the_camera_are_not_drawn_through_the_mirror():
    y = np.linspace(-30, -5, 30)
    behind = Lane(np.stack([np.full_like(y, 1.0), y, np.zeros_like(y)], -1), np.ones(30, np.float32), 2)
    out = draw_lanes_on_image(np.zeros((480, 640, 3), np.uint8), [behind], K, T_LANE_CAM)
    assert not out.any()


def test_top_view_puts_x_zero_in_the_middle_column_and_far_at_the_top():
    view = draw_top_view([straight_lane(0.0, 2)], size=(414, 201), x_range=(-20, 20), y_range=(0, 200))
    color = np.array(CATEGORY_COLORS[2])
    rows, cols = np.nonzero((view == color).all(-1))
    assert abs(np.median(cols) - 100) <= 1
    # the plot above the 14-pixel x axis: y from 3 m to 60 m maps to rows 394 .. 280
    assert 270 <= rows.min() <= 290 and 385 <= rows.max() < 400


def test_top_view_labels_its_x_axis_in_metres_under_the_plot():
    view = TopView((214, 200), (-20.0, 20.0), (0.0, 100.0), axis_height=14)
    canvas = view.canvas()
    axis = canvas[200:]
    text = (axis.max(-1) > 100).any(0)  # label pixels, brighter than the strip and the grid
    for x in (-20.0, -10.0, 0.0, 10.0, 20.0):  # "-20m" .. "20m" centred under their grid lines
        u = int(round(view.pixels(np.array(x), np.array(0.0))[0]))
        assert text[max(u - 6, 0) : u + 7].any(), x
    y = np.linspace(-20, 50, 30)  # reaching behind the ego, below the plot: lanes stay off the axis
    behind = Lane(np.stack([np.zeros_like(y), y, np.zeros_like(y)], -1), np.ones(30), 2)
    np.testing.assert_array_equal(view.draw(canvas.copy(), [behind])[200:], axis)
