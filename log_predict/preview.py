"""The picture of a predicted log, drawn from the written file alone: what Foxglove will show.

A row per chosen frame: the camera image from the log's image topic with the
``foxglove.ImageAnnotations`` of its stamp drawn over it (as the Image panel overlays them),
and a top view of the ``foxglove.SceneUpdate`` lines of the same stamp (what the 3D panel
shows, seen from above, in the lane frame: x right, y ahead of the ego).
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
from lanelab.evaluation.pictures import TOP_VIEW_X_RANGE, label_panel, write_png
from lanelab.geometry import base_link_to_lane
from lanelab.lanes import Lane
from lanelab.store.image_codec import decode_image
from lanelab.viz import CATEGORY_COLORS, draw_polylines, draw_top_view
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
    scenes: dict[int, SceneUpdate] = {}
    annotations: dict[int, ImageAnnotations] = {}
    decoder = Decoder()
    topics = (cfg.topics.image, cfg.predictions.scene, cfg.predictions.annotations)
    for message in read_messages(path, topics, ReadReport(path.stat().st_size)):
        if message.topic == cfg.topics.image:
            image = decoder.decode(message, IMAGE)
            if image.stamp_ns in wanted:
                images[image.stamp_ns] = image
        elif message.topic == cfg.predictions.scene:
            scene = decode_foxglove(message, SceneUpdate)
            entity = scene.entities[0]
            scenes[entity.timestamp.ToNanoseconds()] = scene
        else:
            annotation = decode_foxglove(message, ImageAnnotations)
            if annotation.points:
                annotations[annotation.points[0].timestamp.ToNanoseconds()] = annotation
    first = min(images) if images else 0
    rows = [_row(images[t], scenes.get(t), annotations.get(t), f"{path.stem}  {(t - first) / 1e9:.1f} s", y_range)
            for t in sorted(wanted & set(images))]
    if not rows:
        raise ValueError(f"{path}: none of the {len(wanted)} frames to draw is in the file")
    width = max(row.shape[1] for row in rows)
    return write_png(out, np.vstack([np.pad(row, ((0, 0), (0, width - row.shape[1]), (0, 0))) for row in rows]))


def _row(image: ImageMsg, scene: SceneUpdate | None, annotations: ImageAnnotations | None, title: str,
         y_range: tuple[float, float]) -> np.ndarray:
    """[image + annotations | top view of the scene's lines] at ROW_HEIGHT pixels."""
    picture = np.ascontiguousarray(decode_image(_Encoded(image))[..., ::-1])  # RGB -> BGR
    scale = ROW_HEIGHT / picture.shape[0]
    picture = cv2.resize(picture, (round(picture.shape[1] * scale), ROW_HEIGHT), interpolation=cv2.INTER_AREA)
    for annotation in annotations.points if annotations is not None else ():
        # Pixel coordinates are continuous with edges at integers, so scaling them is exact.
        line = scale * np.array([[p.x, p.y] for p in annotation.points])
        picture = draw_polylines(picture, [line], [_bgr(annotation.outline_color)], max(1, round(annotation.thickness)))
    lanes = [Lane(_lane_frame(line.points), np.ones(len(line.points)), _CATEGORY_OF_COLOR.get(_bgr(line.color), 0))
             for line in _lines(scene)]  # fmt: skip
    top = draw_top_view(lanes, (ROW_HEIGHT, ROW_HEIGHT // 2), TOP_VIEW_X_RANGE, y_range, title="3D lines")
    return np.hstack([label_panel(picture, title), top])


class _Encoded:
    """An ImageMsg as :func:`lanelab.store.image_codec.decode_image` reads images."""

    def __init__(self, image: ImageMsg) -> None:
        self.image, self.image_encoding, self.width, self.height = image.data, image.encoding, image.width, image.height


def _lines(scene: SceneUpdate | None) -> list[Any]:
    return [line for entity in scene.entities for line in entity.lines] if scene is not None else []


def _lane_frame(points: Any) -> np.ndarray:
    """Ego-frame (ROS base_link) points -> the lane frame (P, 3)."""
    return base_link_to_lane(torch.tensor([[p.x, p.y, p.z] for p in points], dtype=torch.float64).reshape(-1, 3)).numpy()


def _bgr(color: Any) -> tuple[int, int, int]:
    return round(255 * color.b), round(255 * color.g), round(255 * color.r)
