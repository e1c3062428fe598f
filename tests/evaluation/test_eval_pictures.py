"""Pictures of evaluated frames: GT and prediction apart and together, over the image and from above."""

import cv2
import numpy as np
from eval_helpers import NAMES, write_prediction_set

from lanelab.evaluation.pictures import PictureFrame, draw_pictures, pick_frames, read_openlane_frame
from lanelab.lanes import Lane
from lanelab.viz import CATEGORY_COLORS, GT_COLOR
from lanelab.viz.panels import strip_height

K = np.array([[100.0, 0, 80], [0, 100, 60], [0, 0, 1]])
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])  # 1.5 m up, looking ahead


def test_frames_are_picked_evenly():
    assert pick_frames(3, 4) == [0, 1, 2]
    assert pick_frames(10, 3) == [0, 4, 9] and pick_frames(10, 0) == []


def test_a_row_shows_gt_and_prediction_apart_and_together_over_a_legend():
    y = np.linspace(3, 60, 40)
    gt = Lane(np.stack([np.full_like(y, 1.0), y, np.zeros_like(y)], -1), np.ones_like(y), 8)  # yellow solid
    frame = PictureFrame("a", np.zeros((120, 160, 3), np.uint8), K, T_LANE_CAM, [gt], [])
    picture = draw_pictures([frame, frame], height=240, y_range=(0.0, 103.0))
    panel_width, strips = 320, 2 * strip_height(240)  # the 160 x 120 image at 240 px high; title and captions
    assert picture.shape[1] == 3 * panel_width + 120
    row = picture[strips : strips + 240]
    yellow, green = (np.all(row == color, axis=-1) for color in (CATEGORY_COLORS[8], GT_COLOR))
    assert yellow[:, :panel_width].any(), "GT over the image, in its category colour"
    assert not yellow[:, panel_width:].any(), "no prediction; GT vs prediction in GT's own colour"
    assert green[:, 2 * panel_width : 3 * panel_width].any() and green[:, 3 * panel_width :].any()
    assert not green[:, : 2 * panel_width].any()
    legend = picture[2 * (strips + 240) :]
    assert legend.shape[0] > 0 and np.all(legend == CATEGORY_COLORS[8], axis=-1).any()  # the category drawn


def test_openlane_frames_are_read_with_and_without_images(tmp_path):
    data = write_prediction_set(tmp_path)
    rel = NAMES["b"].replace(".jpg", ".json")
    frame = read_openlane_frame(data.gt, data.pred, rel, None)
    assert frame.image.shape == (120, 160, 3) and frame.title == "segment-1/15584011356475100"  # 2 cx by 2 cy
    assert len(frame.gt) == 1 and len(frame.pred) == 2 and frame.pred[1].points[0, 0] == 6.0
    np.testing.assert_array_equal(frame.T_lane_cam, T_LANE_CAM)

    image = tmp_path / "images" / NAMES["b"]
    image.parent.mkdir(parents=True)
    cv2.imwrite(str(image), np.full((240, 320, 3), 200, np.uint8))
    assert read_openlane_frame(data.gt, data.pred, rel, tmp_path / "images").image.shape == (240, 320, 3)
