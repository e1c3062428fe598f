"""The messages of a predicted frame, in the encoding of its log.

- ``foxglove.SceneUpdate``: one entity per frame (same id, so each replaces the last) in the
  ego frame, stamped with the image's sensor time, a 3D line strip per lane in its category's
  colour (Foxglove's 3D panel places it through /tf as the car moves);
- ``foxglove.ImageAnnotations``: the same lines projected into the image with the frame's
  calibration and extrinsic, cut at the image border (Foxglove's Image panel overlays them
  on the image of the same stamp);
- ``lanelab.Lanes3D``: every lane with all its samples and their visibility, in the ego frame,
  with its score (so lanelab-ingest reads a predicted log as labels);
- for a frame the log labels, a second ``foxglove.SceneUpdate`` of its ground-truth lanes (their
  labelled-visible parts) in :data:`lanelab.viz.GT_COLOR`, so the 3D panel shows both.

The lines of the first two are the visible part of each lane, exactly what an OpenLane
prediction file holds (:func:`lanelab.openlane.write.prediction_json`). Foxglove types are
protobuf in a protobuf log and Foxglove's JSON otherwise (ROS 2 logs included);
``lanelab.Lanes3D`` is always JSON.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.duration_pb2 import Duration
from google.protobuf.message import Message
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.well_known import MessageEncoding, SchemaEncoding

from data_ingest.contract import LANES3D_TYPE
from data_ingest.synth import lanelab_msgs
from data_ingest.synth.encoders import Schema, foxglove_json_schema, protobuf_schema
from data_ingest.synth.foxglove_json import dumps, to_json
from lanelab.geometry import lane_to_base_link, project_lane_points
from lanelab.lanes import Lane
from lanelab.openlane.write import prediction_json
from lanelab.viz import CATEGORY_COLORS, GT_COLOR
from lanelab.viz.lanes import VISIBLE, Color as BGR

ENTITY_ID = "lanelab/lanes"  # one entity, replaced frame by frame
GT_ENTITY_ID = "lanelab/ground_truth"
LANES3D_SCHEMA = Schema(LANES3D_TYPE, SchemaEncoding.JSONSchema, dumps(lanelab_msgs.SCHEMAS[LANES3D_TYPE]))
_EDGE = 1e-3  # pixels: annotations stop this far inside the right and bottom borders (u < width, v < height)


@dataclass(frozen=True)
class PredictedFrame:
    """A frame's predicted lanes (lane frame, every sample) and the camera they were seen by:
    K (3, 3) and T_lane_cam (4, 4) of the image as logged, width x height pixels; its labelled
    lanes (lane frame) where the log labels it, else None."""

    stamp_ns: int
    lanes: list[Lane]
    K: np.ndarray
    T_lane_cam: np.ndarray
    width: int
    height: int
    labels: list[Lane] | None = None


class FoxgloveEncoding:
    """Foxglove messages as protobuf (``protobuf=True``) or in Foxglove's JSON encoding."""

    def __init__(self, protobuf: bool) -> None:
        self.protobuf = protobuf
        self.message_encoding = MessageEncoding.Protobuf if protobuf else MessageEncoding.JSON

    def schema(self, message_type: type[Message]) -> Schema:
        return protobuf_schema(message_type) if self.protobuf else foxglove_json_schema(message_type)

    def serialize(self, message: Message) -> bytes:
        return message.SerializeToString() if self.protobuf else dumps(to_json(message))


def visible_lines(lanes: Sequence[Lane], threshold: float) -> list[Lane]:
    """The lanes as an OpenLane prediction file holds them: the points of visibility above
    ``threshold``, lanes left with two or more."""
    scores = [lane.score for lane in lanes]
    lines = prediction_json("", lanes, threshold, None if None in scores else scores)["lane_lines"]
    return [Lane(np.asarray(line["xyz"]), np.asarray(line["visibility"]), line["category"], score=line.get("score"))
            for line in lines]  # fmt: skip


def labelled_lines(frame: PredictedFrame) -> list[Lane]:
    """The parts of the frame's ground-truth lanes labelled visible (as :func:`visible_lines`)."""
    return visible_lines(frame.labels or [], VISIBLE)


def rgba(category: int) -> Color:
    """The category's colour of lanelab.viz (BGR bytes) as a Foxglove colour."""
    return foxglove_color(CATEGORY_COLORS.get(int(category), CATEGORY_COLORS[0]))


def foxglove_color(bgr: BGR) -> Color:
    """A lanelab.viz colour (BGR bytes) as a Foxglove colour."""
    blue, green, red = bgr
    return Color(r=red / 255, g=green / 255, b=blue / 255, a=1.0)


def to_ego(points: np.ndarray) -> np.ndarray:
    """Lane-frame points (P, 3) -> the ego frame (ROS base_link axes) (P, 3)."""
    return lane_to_base_link(torch.from_numpy(np.asarray(points, dtype=np.float64))).numpy()


def _timestamp(stamp_ns: int) -> Timestamp:
    return Timestamp(seconds=stamp_ns // 1_000_000_000, nanos=stamp_ns % 1_000_000_000)


def scene_update(frame: PredictedFrame, lines: Sequence[Lane], ego_frame: str, width: float,
                 lifetime_ns: int, color: BGR | None = None, entity_id: str = ENTITY_ID) -> SceneUpdate:
    """One entity ``entity_id`` in ``ego_frame`` with a line strip of ``width`` metres per line,
    in its category's colour or ``color``, shown for ``lifetime_ns`` unless the next frame's
    replaces it."""
    identity = Pose(orientation=Quaternion(w=1.0))
    entity = SceneEntity(
        timestamp=_timestamp(frame.stamp_ns), frame_id=ego_frame, id=entity_id,
        lifetime=Duration(seconds=lifetime_ns // 1_000_000_000, nanos=lifetime_ns % 1_000_000_000),
        lines=[LinePrimitive(type=LinePrimitive.LINE_STRIP, pose=identity, thickness=width, scale_invariant=False,
                             points=[Point3(x=x, y=y, z=z) for x, y, z in to_ego(line.points).tolist()],
                             color=rgba(line.category) if color is None else foxglove_color(color))
               for line in lines],
    )  # fmt: skip
    return SceneUpdate(entities=[entity])


def image_annotations(frame: PredictedFrame, lines: Sequence[Lane], thickness: float) -> ImageAnnotations:
    """The lines projected into the frame's image, a line strip per piece inside the image."""
    annotations = []
    for line in lines:
        uv, _, in_front = project_lane_points(*(torch.from_numpy(np.asarray(a, dtype=np.float64))
                                                for a in (line.points, frame.K, frame.T_lane_cam)))
        for piece in clip_to_image(uv.numpy(), in_front.numpy(), frame.width, frame.height):
            annotations.append(PointsAnnotation(
                timestamp=_timestamp(frame.stamp_ns), type=PointsAnnotation.LINE_STRIP,
                points=[Point2(x=u, y=v) for u, v in piece.tolist()], outline_color=rgba(line.category),
                thickness=thickness,
            ))  # fmt: skip
    return ImageAnnotations(timestamp=_timestamp(frame.stamp_ns), points=annotations)


def ground_truth_scene(frame: PredictedFrame, ego_frame: str, width: float, lifetime_ns: int) -> SceneUpdate:
    """The frame's ground-truth lines (:func:`labelled_lines`) as :func:`scene_update`'s entity
    :data:`GT_ENTITY_ID`, in :data:`lanelab.viz.GT_COLOR`."""
    return scene_update(frame, labelled_lines(frame), ego_frame, width, lifetime_ns, GT_COLOR, GT_ENTITY_ID)


def lanes3d(frame: PredictedFrame, ego_frame: str) -> bytes:
    """The frame's lanes as a ``lanelab.Lanes3D`` message in ``ego_frame``, with scores."""
    lanes = [Lane(to_ego(lane.points), np.asarray(lane.visibility), lane.category, track_id=lane.track_id,
                  score=lane.score) for lane in frame.lanes]  # fmt: skip
    return dumps(lanelab_msgs.lanes3d(frame.stamp_ns, ego_frame, lanes, scores=True))


def clip_to_image(uv: np.ndarray, in_front: np.ndarray, width: int, height: int) -> list[np.ndarray]:
    """The pieces (Q, 2) of the polyline uv (P, 2) that lie inside a width x height image
    (u < width, v < height): segments between points in front of the camera (in_front (P,)),
    cut where they cross the border."""
    low, high = np.zeros(2), np.array([width, height], dtype=np.float64) - _EDGE
    pieces: list[list[np.ndarray]] = []
    current: list[np.ndarray] = []
    for a, b, both in zip(uv[:-1], uv[1:], in_front[:-1] & in_front[1:]):
        clipped = _clip_segment(a, b, low, high) if both else None
        if clipped is None:
            current = []
            continue
        start, end = clipped
        if not current or not np.array_equal(current[-1], start):
            current = [start]
            pieces.append(current)
        current.append(end)
    return [np.array(piece) for piece in pieces]


def _clip_segment(a: np.ndarray, b: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The part of segment a -> b inside the box [low, high] (Liang-Barsky), or None; an end
    inside the box is returned as it is, so consecutive pieces join exactly."""
    d = b - a
    t0, t1 = 0.0, 1.0
    for axis in range(2):
        for p, q in ((-d[axis], a[axis] - low[axis]), (d[axis], high[axis] - a[axis])):
            if p == 0:
                if q < 0:
                    return None
            elif p < 0:
                t0 = max(t0, q / p)
            else:
                t1 = min(t1, q / p)
    if t0 > t1:
        return None
    start = a if t0 == 0 else np.clip(a + t0 * d, low, high)
    end = b if t1 == 1 else np.clip(a + t1 * d, low, high)
    return start, end
