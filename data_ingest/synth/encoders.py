"""Sensor messages (images, calibration, transforms) in each encoding a drive log can use.

Every encoder has the same methods and returns serialized message bytes plus the schema
record to register for them, so the MCAP writer walks a drive once whatever the encoding:

- :class:`Ros2Encoder`: ROS 2 types (``ros2msg`` schemas, ``cdr`` messages);
- :class:`FoxgloveProtobufEncoder`: Foxglove types as ``protobuf``;
- :class:`FoxgloveJsonEncoder`: the same Foxglove types as ``jsonschema`` / ``json``.

Stamps are sensor times (int64 ns): ROS ``header.stamp``, Foxglove ``timestamp``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol, Sequence

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.message import Message
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap_protobuf.schema import build_file_descriptor_set

# mcap_ros2's own Writer encodes with these functions, but it owns its mcap.writer.Writer
# with no public handle, so a file that also holds JSON channels uses them directly. The module
# is private: pyproject pins mcap-ros2-support to the versions tests/synth/test_ros2_cdr.py passed on.
from mcap_ros2._dynamic import serialize_dynamic

from data_ingest.synth import ros2_msgdefs
from data_ingest.synth.foxglove_json import dumps, json_schema, to_json
from data_ingest.synth.frame import CameraModel

# Roles of the sensor channels; each encoder maps them to its own message types.
TRANSFORMS = "transforms"
COMPRESSED_IMAGE = "compressed_image"
RAW_IMAGE = "raw_image"
CALIBRATION = "calibration"

RAW_ENCODING = "bgr8"  # SynthFrame.image is BGR, OpenCV's order
DISTORTION_MODEL = "plumb_bob"


@dataclass(frozen=True)
class Schema:
    """What an MCAP schema record holds."""

    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class StampedTransform:
    """parent <- child at a sensor time: maps points of ``child`` into ``parent``.

    translation: (3,) metres; rotation: (4,) unit quaternion (x, y, z, w).
    """

    stamp_ns: int
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


class MessageEncoder(Protocol):
    """Builds and serializes the sensor messages of one encoding."""

    profile: str  # the MCAP header's profile
    message_encoding: str

    def schema(self, role: str) -> Schema: ...

    def transforms(self, transforms: Sequence[StampedTransform]) -> bytes: ...

    def compressed_image(self, t_ns: int, frame_id: str, data: bytes, fmt: str) -> bytes: ...

    def raw_image(self, t_ns: int, frame_id: str, image: np.ndarray) -> bytes: ...

    def calibration(self, t_ns: int, camera: CameraModel) -> bytes: ...


def protobuf_schema(message_type: type[Message]) -> Schema:
    """The schema record of a protobuf message type: its file descriptor set."""
    descriptor_set = build_file_descriptor_set(message_type)
    return Schema(message_type.DESCRIPTOR.full_name, SchemaEncoding.Protobuf, descriptor_set.SerializeToString())


def foxglove_json_schema(message_type: type[Message]) -> Schema:
    """The schema record of a Foxglove message type in Foxglove's JSON encoding."""
    descriptor = message_type.DESCRIPTOR
    return Schema(descriptor.full_name, SchemaEncoding.JSONSchema, dumps(json_schema(descriptor)))


def calibration_arrays(camera: CameraModel) -> dict[str, list[float]]:
    """An undistorted pinhole camera as CameraInfo arrays: D (5,), K (9,), R (9,), P (12,), row-major."""
    K = np.asarray(camera.K, dtype=np.float64)
    return {
        "D": [0.0] * 5,
        "K": K.ravel().tolist(),
        "R": np.eye(3).ravel().tolist(),
        "P": np.hstack([K, np.zeros((3, 1))]).ravel().tolist(),
    }


def _raw_bytes(image: np.ndarray) -> bytes:
    """(H, W, 3) uint8 BGR image -> row-major bytes, step = 3 * W."""
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"raw images must be (H, W, 3) uint8, got {image.shape} {image.dtype}")
    return np.ascontiguousarray(image).tobytes()


class Ros2Encoder:
    """ROS 2 messages: sensor_msgs Image / CompressedImage / CameraInfo, tf2_msgs TFMessage."""

    profile = "ros2"
    message_encoding = MessageEncoding.CDR
    _TYPES = {
        TRANSFORMS: ros2_msgdefs.TF_MESSAGE,
        COMPRESSED_IMAGE: ros2_msgdefs.COMPRESSED_IMAGE,
        RAW_IMAGE: ros2_msgdefs.IMAGE,
        CALIBRATION: ros2_msgdefs.CAMERA_INFO,
    }

    def __init__(self) -> None:
        self._schemas = {
            role: Schema(name, SchemaEncoding.ROS2, ros2_msgdefs.msgdef(name).encode())
            for role, name in self._TYPES.items()
        }
        self._cdr: dict[str, Callable[[Any], bytes]] = {
            role: serialize_dynamic(schema.name, schema.data.decode())[schema.name]
            for role, schema in self._schemas.items()
        }

    def schema(self, role: str) -> Schema:
        return self._schemas[role]

    @staticmethod
    def _header(t_ns: int, frame_id: str) -> dict[str, Any]:
        sec, nanosec = divmod(t_ns, 1_000_000_000)
        return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame_id}

    def transforms(self, transforms: Sequence[StampedTransform]) -> bytes:
        return self._cdr[TRANSFORMS](
            {
                "transforms": [
                    {
                        "header": self._header(tf.stamp_ns, tf.parent),
                        "child_frame_id": tf.child,
                        "transform": {
                            "translation": dict(zip("xyz", tf.translation)),
                            "rotation": dict(zip("xyzw", tf.rotation)),
                        },
                    }
                    for tf in transforms
                ]
            }
        )

    def compressed_image(self, t_ns: int, frame_id: str, data: bytes, fmt: str) -> bytes:
        return self._cdr[COMPRESSED_IMAGE]({"header": self._header(t_ns, frame_id), "format": fmt, "data": data})

    def raw_image(self, t_ns: int, frame_id: str, image: np.ndarray) -> bytes:
        height, width = image.shape[:2]
        return self._cdr[RAW_IMAGE](
            {
                "header": self._header(t_ns, frame_id),
                "height": height,
                "width": width,
                "encoding": RAW_ENCODING,
                "is_bigendian": 0,
                "step": 3 * width,
                "data": _raw_bytes(image),
            }
        )

    def calibration(self, t_ns: int, camera: CameraModel) -> bytes:
        arrays = calibration_arrays(camera)
        return self._cdr[CALIBRATION](
            {
                "header": self._header(t_ns, camera.frame_id),
                "height": camera.height,
                "width": camera.width,
                "distortion_model": DISTORTION_MODEL,
                "d": arrays["D"],
                "k": arrays["K"],
                "r": arrays["R"],
                "p": arrays["P"],
            }
        )


class FoxgloveProtobufEncoder:
    """Foxglove messages as protobuf: CompressedImage, RawImage, CameraCalibration, FrameTransforms."""

    profile = ""  # MCAP has no profile for Foxglove schemas
    message_encoding = MessageEncoding.Protobuf
    _TYPES: dict[str, type[Message]] = {
        TRANSFORMS: FrameTransforms,
        COMPRESSED_IMAGE: CompressedImage,
        RAW_IMAGE: RawImage,
        CALIBRATION: CameraCalibration,
    }

    def schema(self, role: str) -> Schema:
        return protobuf_schema(self._TYPES[role])

    def _serialize(self, message: Message) -> bytes:
        return message.SerializeToString()

    @staticmethod
    def _timestamp(t_ns: int) -> Timestamp:
        sec, nsec = divmod(t_ns, 1_000_000_000)
        return Timestamp(seconds=sec, nanos=nsec)

    def transforms(self, transforms: Sequence[StampedTransform]) -> bytes:
        return self._serialize(
            FrameTransforms(
                transforms=[
                    FrameTransform(
                        timestamp=self._timestamp(tf.stamp_ns),
                        parent_frame_id=tf.parent,
                        child_frame_id=tf.child,
                        translation=Vector3(**dict(zip("xyz", tf.translation))),
                        rotation=Quaternion(**dict(zip("xyzw", tf.rotation))),
                    )
                    for tf in transforms
                ]
            )
        )

    def compressed_image(self, t_ns: int, frame_id: str, data: bytes, fmt: str) -> bytes:
        return self._serialize(
            CompressedImage(timestamp=self._timestamp(t_ns), frame_id=frame_id, data=data, format=fmt)
        )

    def raw_image(self, t_ns: int, frame_id: str, image: np.ndarray) -> bytes:
        height, width = image.shape[:2]
        return self._serialize(
            RawImage(
                timestamp=self._timestamp(t_ns),
                frame_id=frame_id,
                width=width,
                height=height,
                encoding=RAW_ENCODING,
                step=3 * width,
                data=_raw_bytes(image),
            )
        )

    def calibration(self, t_ns: int, camera: CameraModel) -> bytes:
        return self._serialize(
            CameraCalibration(
                timestamp=self._timestamp(t_ns),
                frame_id=camera.frame_id,
                width=camera.width,
                height=camera.height,
                distortion_model=DISTORTION_MODEL,
                **calibration_arrays(camera),
            )
        )


class FoxgloveJsonEncoder(FoxgloveProtobufEncoder):
    """The same Foxglove messages in Foxglove's JSON encoding (bytes as base64)."""

    message_encoding = MessageEncoding.JSON

    def schema(self, role: str) -> Schema:
        return foxglove_json_schema(self._TYPES[role])

    def _serialize(self, message: Message) -> bytes:
        return dumps(to_json(message))


def make_encoder(encoding: str, foxglove_schema: str) -> MessageEncoder:
    """The encoder for ``encoding`` (ros2 | foxglove) and, for foxglove, ``foxglove_schema`` (protobuf | json)."""
    if encoding == "ros2":
        return Ros2Encoder()
    if encoding == "foxglove":
        return {"protobuf": FoxgloveProtobufEncoder, "json": FoxgloveJsonEncoder}[foxglove_schema]()
    raise ValueError(f"unknown encoding {encoding!r}")
