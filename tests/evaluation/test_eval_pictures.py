"""Pictures of evaluated frames: GT and prediction side by side, over the image and from above."""

import cv2
import numpy as np
from eval_helpers import NAMES, write_prediction_set

from lanelab.evaluation.pictures import PictureFrame, draw_pictures, pick_frames, read_openlane_frame
from lanelab.lanes import Lane
from lanelab.viz import CATEGORY_COLORS

K = np.array([[100.0, 0, 80], [0, 100, 60], [0, 0, 1]])
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])  # 1.5 m up, looking ahead


def test_frames_are_picked_evenly():
    assert pick_frames(3, 4) == [0, 1, 2]
    assert pick_frames(10, 3) == [0, 4, 9] and pick_frames(10, 0) == []


def test_a_row_shows_gt_and_prediction_in_separate_panels():
    y = np.linspace(3, 60, 40)
    gt = Lane(np.stack([np.full_like(y, 1.0), y, np.zeros_like(y)], -1), np.ones_like(y), 8)  # yellow solid
    frame = PictureFrame("a", np.zeros((120, 160, 3), np.uint8), K, T_LANE_CAM, [gt], [])
    picture = draw_pictures([frame, frame], height=240, y_range=(0.0, 103.0))
    panel_width = 320  # the 160 x 120 image at 240 px high
    assert picture.shape == (480, 2 * panel_width + 2 * 120, 3)
    yellow = np.all(picture == CATEGORY_COLORS[8], axis=-1)
    assert yellow[:240, :panel_width].any(), "GT over the image"
    assert not yellow[:240, panel_width:2 * panel_width].any(), "no prediction over the image"
    assert yellow[:240, 2 * panel_width:2 * panel_width + 120].any(), "GT from above"
    assert not yellow[:240, 2 * panel_width + 120:].any()


def test_openlane_frames_are_read_with_and_without_images(tmp_path):
    data = write_prediction_set(tmp_path)
    rel = NAMES["b"].replace(".jpg", ".json")
    frame = read_openlane_frame(data.gt, data.pred, rel, None)
    assert frame.image.shape == (120, 160, 3) and frame.title == "15584011356475100"  # 2 cx by 2 cy
    assert len(frame.gt) == 1 and len(frame.pred) == 2 and frame.pred[1].points[0, 0] == 6.0
    np.testing.assert_array_equal(frame.T_lane_cam, T_LANE_CAM)

    image = tmp_path / "images" / NAMES["b"]
    image.parent.mkdir(parents=True)
    cv2.imwrite(str(image), np.full((240, 320, 3), 200, np.uint8))
    assert read_openlane_frame(data.gt, data.pred, rel, tmp_path / "images").image.shape == (240, 320, 3)
