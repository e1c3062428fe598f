"""The picture of a predicted log, drawn from the written file alone: what Foxglove will show.

A row per chosen frame: the camera image from the log's image topic with the
``foxglove.ImageAnnotations`` of its stamp drawn over it (as the Image panel overlays them),
and a top view of the ``foxglove.SceneUpdate`` lines of the same stamp (what the 3D panel
shows, seen from above, in the lane frame: x right, y ahead of the ego): the predictions in
their categories' colours over the ground truth's wider green lines where the log has labels.
Every row's top view spans the same x range, wide enough for every line (at least ±20 m); a
legend of the colours closes the picture.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Collection

import cv2
import numpy as np
import torch
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.message import Message
from mcap.well_known import MessageEncoding

from data_ingest.contract import IMAGE
from data_ingest.ingest.mcap_reader import RawMessage, ReadReport, read_messages
from data_ingest.ingest.messages import Decoder, ImageMsg
from data_ingest.synth.foxglove_json import from_json
from lanelab.evaluation.pictures import label_panel, write_png
from lanelab.geometry import base_link_to_lane
from lanelab.lanes import Lane
from lanelab.store.image_codec import decode_image
from lanelab.viz import CATEGORY_COLORS, GT_COLOR, draw_polylines
from lanelab.viz.lanes import AXIS_HEIGHT, TITLE_HEIGHT, TopView, fit_x_range, top_view_width
from lanelab.viz.panels import categories_of, stack_rows
from lanelab.viz.text import text_strip
from log_predict.config import PredictConfig

ROW_HEIGHT = 240  # pixels
# The 3D lines carry their category as their colour (log_predict.messages.rgba).
_CATEGORY_OF_COLOR = {color: category for category, color in CATEGORY_COLORS.items()}


def decode_foxglove(message: RawMessage, message_type: type[Message]) -> Message:
    """A Foxglove message of a protobuf or JSON channel as its protobuf type."""
    if message.channel.message_encoding == MessageEncoding.Protobuf:
        return message_type.FromString(message.data)
    return from_json(json.loads(message.data), message_type)


def draw_preview(path: Path, cfg: PredictConfig, stamps: Collection[int], y_range: tuple[float, float],
                 out: Path) -> Path:
    """Draw the frames of ``stamps`` (image sensor times, ns) of the predicted log at ``path``
    into the PNG ``out`` (written atomically); top views over y_range (metres)."""
    wanted = set(stamps)
    images: dict[int, ImageMsg] = {}
    scenes: dict[int, list[Lane]] = {}
    truths: dict[int, list[Lane]] = {}
    annotations: dict[int, ImageAnnotations] = {}
    decoder = Decoder()
    topics = (cfg.topics.image, cfg.predictions.scene, cfg.predictions.ground_truth, cfg.predictions.annotations)
    for message in read_messages(path, topics, ReadReport(path.stat().st_size)):
        if message.topic == cfg.topics.image:
            image = decoder.decode(message, IMAGE)
            if image.stamp_ns in wanted:
                images[image.stamp_ns] = image
        elif message.topic == cfg.predictions.annotations:
            annotation = decode_foxglove(message, ImageAnnotations)
            annotations[annotation.timestamp.ToNanoseconds()] = annotation
        else:
            (entity,) = decode_foxglove(message, SceneUpdate).entities
            lanes = scenes if message.topic == cfg.predictions.scene else truths
            lanes[entity.timestamp.ToNanoseconds()] = [_lane(line) for line in entity.lines]
    drawn = sorted(wanted & set(images))
    if not drawn:
        raise ValueError(f"{path}: none of the {len(wanted)} frames to draw is in the file")
    x_range = fit_x_range([lane for t in drawn for lane in (*scenes.get(t, []), *truths.get(t, []))], y_range)
    first = min(images)
    rows = [_row(images[t], scenes.get(t, []), truths.get(t, []), annotations.get(t),
                 f"{path.stem}  {(t - first) / 1e9:.1f} s", x_range, y_range) for t in drawn]  # fmt: skip
    categories = categories_of(*(scenes.get(t, []) for t in drawn))
    kinds = ("ground truth",) if any(t in truths for t in drawn) else ()
    return write_png(out, stack_rows(rows, categories, ROW_HEIGHT, kinds))


def _row(image: ImageMsg, predicted: list[Lane], truth: list[Lane], annotations: ImageAnnotations | None, title: str,
         x_range: tuple[float, float], y_range: tuple[float, float]) -> np.ndarray:
    """[image + annotations | top view of the ground truth and predicted lines] at ROW_HEIGHT pixels."""
    picture = np.ascontiguousarray(decode_image(_Encoded(image))[..., ::-1])  # RGB -> BGR
    scale = ROW_HEIGHT / picture.shape[0]
    picture = cv2.resize(picture, (round(picture.shape[1] * scale), ROW_HEIGHT), interpolation=cv2.INTER_AREA)
    for annotation in annotations.points if annotations is not None else ():
        # Pixel coordinates are continuous with edges at integers, so scaling them is exact.
        line = scale * np.array([[p.x, p.y] for p in annotation.points])
        picture = draw_polylines(picture, [line], [_bgr(annotation.outline_color)], max(1, round(annotation.thickness)))
    width = top_view_width(ROW_HEIGHT, x_range, y_range)
    view = TopView((ROW_HEIGHT - TITLE_HEIGHT, width), x_range, y_range, axis_height=AXIS_HEIGHT)
    top = view.draw(view.canvas(), truth, thickness=4, show_hidden=False, color=GT_COLOR)
    top = view.draw(top, predicted, thickness=2, show_hidden=False)
    return np.hstack([label_panel(picture, title), np.vstack([text_strip([("3D panel", width)], TITLE_HEIGHT), top])])


class _Encoded:
    """An ImageMsg as :func:`lanelab.store.image_codec.decode_image` reads images."""

    def __init__(self, image: ImageMsg) -> None:
        self.image, self.image_encoding, self.width, self.height = image.data, image.encoding, image.width, image.height


def _lane(line: Any) -> Lane:
    """A 3D line of the scene (ego frame, ROS base_link) as a lane in the lane frame, its
    category read from its colour (ground truth's green reads as category 0)."""
    points = torch.tensor([[p.x, p.y, p.z] for p in line.points], dtype=torch.float64).reshape(-1, 3)
    return Lane(base_link_to_lane(points).numpy(), np.ones(len(points)), _CATEGORY_OF_COLOR.get(_bgr(line.color), 0))


def _bgr(color: Any) -> tuple[int, int, int]:
    return round(255 * color.b), round(255 * color.g), round(255 * color.r)
