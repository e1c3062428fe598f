"""Pictures of evaluated frames: ground truth and prediction over the camera image and in a
top view, one row per frame, so that a reader sees what the numbers stand for.

A row is :func:`lanelab.viz.panels.comparison_row`'s: the frame's name over
``[image + GT | image + prediction | image + GT vs prediction | top view of GT vs prediction]``
(categories in their colours, then ground truth green against prediction magenta, the top
view in metres); a legend of the colours closes the picture. Predictions from OpenLane files
hold only visible points.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np

from lanelab.atomic_file import atomic_output
from lanelab.json_files import LaneFileError
from lanelab.lanes import Lane
from lanelab.openlane.lists import frame_key
from lanelab.openlane.read import read_ground_truth, read_prediction
from lanelab.viz.panels import categories_of, comparison_row, stack_rows

TOP_VIEW_X_RANGE = (-15.0, 15.0)  # metres: the evaluated |x| < 10 and a margin
_TEXT_COLOR, _SHADOW_COLOR = (255, 255, 255), (0, 0, 0)  # label_panel


@dataclass(frozen=True)
class PictureFrame:
    """An evaluated frame to draw: image (H, W, 3) uint8 BGR, K (3, 3), T_lane_cam (4, 4),
    its ground-truth and predicted lanes, and a title (the frame's name)."""

    title: str
    image: np.ndarray
    K: np.ndarray
    T_lane_cam: np.ndarray
    gt: list[Lane]
    pred: list[Lane]


def pick_frames(num_frames: int, wanted: int) -> list[int]:
    """Indices of `wanted` frames spread evenly over num_frames (all of them when fewer)."""
    if num_frames <= wanted:
        return list(range(num_frames))
    return sorted({int(i) for i in np.linspace(0, num_frames - 1, wanted).round()})


def draw_row(frame: PictureFrame, height: int, y_range: tuple[float, float]) -> np.ndarray:
    """One frame's row (captions + height, W, 3): image scaled to `height`, top view over y_range."""
    return comparison_row(frame.image, frame.K, frame.T_lane_cam, frame.gt, frame.pred, height, TOP_VIEW_X_RANGE,
                          y_range, frame.title)  # fmt: skip


def draw_pictures(frames: Sequence[PictureFrame], height: int, y_range: tuple[float, float]) -> np.ndarray:
    """The rows of frames stacked (narrower rows padded black on the right) over a legend of
    the categories drawn."""
    rows = [draw_row(frame, height, y_range) for frame in frames]
    return stack_rows(rows, categories_of(*(frame.gt for frame in frames), *(frame.pred for frame in frames)), height)


def write_png(path: str | os.PathLike[str], picture: np.ndarray) -> Path:
    """Write a BGR picture (H, W, 3) as PNG, atomically; its path."""
    ok, data = cv2.imencode(".png", picture)
    if not ok:
        raise ValueError(f"{path}: cannot encode the picture as PNG")
    with atomic_output(path) as tmp:
        tmp.write_bytes(data.tobytes())
    return Path(path)


def read_openlane_frame(
    gt_dir: str | os.PathLike[str],
    pred_dir: str | os.PathLike[str],
    frame_id: str,
    images_dir: str | os.PathLike[str] | None,
) -> PictureFrame:
    """An evaluated OpenLane frame from its files: frame_id is the JSON path relative to
    gt_dir and pred_dir (a test-list id). The image is ``<images_dir>/<file_path>``; without
    images_dir the lanes are drawn on a dark canvas of the camera's size (2 cx by 2 cy).
    The lane frame is the evaluator's ground frame, T_lane_cam its conversion of the extrinsic.
    """
    gt_path = Path(gt_dir) / frame_id
    gt = read_ground_truth(gt_path)
    K, T_lane_cam = gt.K, gt.T_ground_cam
    pred = read_prediction(Path(pred_dir) / frame_id)
    if images_dir is None:
        size = (max(int(round(2 * K[1, 2])), 16), max(int(round(2 * K[0, 2])), 16))
        image = np.full((*size, 3), 40, np.uint8)
    else:
        image_path = Path(images_dir) / gt.file_path
        image = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
        if image is None:
            raise LaneFileError(image_path, f"cannot read the image of {gt_path}")
    return PictureFrame(
        title=frame_key(frame_id),
        image=image,
        K=K,
        T_lane_cam=T_lane_cam,
        gt=[Lane(p, v, c) for p, v, c in zip(gt.lanes, gt.visibility, gt.categories)],
        pred=[Lane(_with_z(p), np.ones(len(p)), c) for p, c in zip(pred.lanes, pred.categories)],
    )


def _with_z(lane: np.ndarray) -> np.ndarray:
    """Prediction points (N, 2 or more) -> (N, 3), z = 0 for two columns, as the evaluator reads them."""
    points = np.zeros((len(lane), 3))
    points[:, : min(lane.shape[1], 3)] = lane[:, :3]
    return points


def label_panel(panel: np.ndarray, text: str) -> np.ndarray:
    """panel with text written in its top-left corner, shadowed so that it reads on any image."""
    for color, thickness in ((_SHADOW_COLOR, 3), (_TEXT_COLOR, 1)):
        cv2.putText(panel, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, color, thickness, cv2.LINE_AA)
    return panel
