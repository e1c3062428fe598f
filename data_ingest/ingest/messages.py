"""The messages of a drive log, in any encoding of the contract, as encoding-neutral records.

The types each role accepts are the drive-log contract's (:mod:`data_ingest.contract`).
CDR and protobuf payloads are decoded by the ``mcap`` library's decoder factories, JSON
with ``json.loads``; Foxglove JSON writes bytes as base64 and times as ``{sec, nsec}``.
``lanelab.Lanes3D`` labels, large arrays of numbers, are parsed in batches by Arrow's JSON
reader (:func:`parse_lanes3d`), several times faster than ``json.loads``.
"""

from __future__ import annotations

import base64
import io
import json
from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.json as pa_json
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from data_ingest.contract import CALIBRATION, IMAGE, JSON_ONLY, LANES2D, OCCLUDERS, TAGS, TRANSFORMS, TYPES
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.mcap_reader import RawMessage
from lanelab.store.image_codec import (
    COMPRESSED_ENCODINGS,
    RAW_CHANNELS,
    compressed_format,
    compressed_size,
    decode_compressed,
)

NS = 1_000_000_000


class MessageError(ValueError):
    """One message that does not hold what its type promises (the log goes on without it)."""


@dataclass(frozen=True)
class ImageMsg:
    """An image. encoding: jpeg | png | rgb8 | bgr8 | mono8; data: the bytes to store (raw rows unpadded)."""

    stamp_ns: int
    frame_id: str
    encoding: str
    width: int
    height: int
    data: bytes


@dataclass(frozen=True)
class CalibrationMsg:
    """Pinhole intrinsics K (3, 3) of the camera ``frame_id`` for images of ``width`` x ``height`` (0: unset)."""

    stamp_ns: int
    frame_id: str
    width: int
    height: int
    K: np.ndarray


@dataclass(frozen=True)
class Transform:
    """parent <- child at ``stamp_ns``: translation (3,) metres, rotation (4,) quaternion (x, y, z, w)."""

    stamp_ns: int
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


@dataclass(frozen=True)
class LanesMsg:
    """A ``lanelab.Lanes3D`` label: L lanes with P points in all, in ``frame_id`` at ``stamp_ns``.

    track_ids, categories, num_points: (L,) int64; points: (P, 3) float64; visibility: (P,) float32.
    Lane k owns points ``sum(num_points[:k])`` to ``sum(num_points[:k + 1]) - 1``.
    """

    stamp_ns: int
    frame_id: str
    track_ids: np.ndarray
    categories: np.ndarray
    num_points: np.ndarray
    points: np.ndarray
    visibility: np.ndarray


@dataclass(frozen=True)
class Detection2D:
    """One 2D lane detection: uv (P, 2) float64 pixels, its score and OpenLane category."""

    uv: np.ndarray
    score: float
    category: int


@dataclass(frozen=True)
class Lanes2DMsg:
    """A ``lanelab.Lanes2D`` message: the 2D lane detections in the image of camera ``frame_id``."""

    stamp_ns: int
    frame_id: str
    lanes: list[Detection2D]


@dataclass(frozen=True)
class TagsMsg:
    stamp_ns: int
    tags: dict[str, str]


def type_name(schema: Optional[Schema]) -> str:
    """The schema's type with ROS 2's ``/msg/`` dropped: "sensor_msgs/msg/Image" -> "sensor_msgs/Image"."""
    return schema.name.replace("/msg/", "/") if schema is not None else ""


def check_schema(path: object, topic: str, role: str, schema: Optional[Schema], message_encoding: str) -> None:
    """Raise :class:`LogError` when ``topic`` does not carry one of the role's types in a known encoding."""
    name = type_name(schema)
    json_role = role in JSON_ONLY
    known_type = name in TYPES[role] or (json_role and schema is None)  # JSON may come without a schema
    known_encoding = message_encoding == "json" if json_role else message_encoding in ("cdr", "protobuf", "json")
    if not (known_type and known_encoding):
        described = (f"{schema.name!r} ({schema.encoding}/{message_encoding})" if schema
                     else f"no schema ({message_encoding})")
        raise LogError(f"{path}: topic {topic} has unknown schema {described}; "
                       f"expected one of {', '.join(TYPES[role])}" + (" as json" if json_role else ""))


class Decoder:
    """Decodes the messages of one log into the records above (decoders are cached per channel)."""

    def __init__(self) -> None:
        self._factories = [Ros2DecoderFactory(), ProtobufDecoderFactory()]
        self._decoders: dict[int, Callable[[bytes], Any]] = {}

    def decode(self, raw: RawMessage, role: str) -> ImageMsg | CalibrationMsg | list[Transform] | Lanes2DMsg | TagsMsg:
        """The record of a message of ``role`` (not ``LANES``: see :func:`parse_lanes3d`); MessageError if unusable."""
        message, name = self._deserialize(raw), type_name(raw.schema)
        try:
            return _CONVERTERS[role](message, name)
        except MessageError:
            raise
        except (KeyError, TypeError, AttributeError, ValueError) as err:  # a field missing or of another type
            raise MessageError(f"not a valid {name or role} message: {type(err).__name__}: {err}") from None

    def _deserialize(self, raw: RawMessage) -> Any:
        decode = self._decoders.get(raw.channel.id)
        if decode is None:
            encoding = raw.channel.message_encoding
            if encoding == "json":
                decode = json.loads
            else:
                decode = next(filter(None, (f.decoder_for(encoding, raw.schema) for f in self._factories)), None)
            if decode is None:
                raise MessageError(f"no decoder for {encoding} messages of schema {type_name(raw.schema)!r}")
            self._decoders[raw.channel.id] = decode
        try:
            return decode(raw.data)
        except Exception as err:  # each library raises its own types for a garbled payload
            raise MessageError(f"cannot decode: {type(err).__name__}: {err}") from None


def _image(m: Any, name: str) -> ImageMsg:
    if name.startswith("sensor_msgs/"):
        stamp, frame_id = _ros_header(m)
        if name.endswith("CompressedImage"):
            return _compressed(stamp, frame_id, m.format, bytes(m.data))
        return _raw(stamp, frame_id, m.encoding, m.width, m.height, m.step, bytes(m.data))
    stamp, frame_id, data = _fox_time(_get(m, "timestamp")), _get(m, "frame_id"), _fox_bytes(_get(m, "data"))
    if name == "foxglove.CompressedImage":
        return _compressed(stamp, frame_id, _get(m, "format"), data)
    return _raw(stamp, frame_id, _get(m, "encoding"), _get(m, "width"), _get(m, "height"), _get(m, "step"), data)


def _calibration(m: Any, name: str) -> CalibrationMsg:
    if name.startswith("sensor_msgs/"):
        (stamp, frame_id), k = _ros_header(m), m.k
    else:
        stamp, frame_id, k = _fox_time(_get(m, "timestamp")), _get(m, "frame_id"), _get(m, "K")
    K = np.asarray(list(k), dtype=np.float64)
    if K.shape != (9,):
        raise MessageError(f"K has {K.size} values, not 9")
    return CalibrationMsg(stamp, frame_id, int(_get(m, "width")), int(_get(m, "height")), K.reshape(3, 3))


def _transforms(m: Any, name: str) -> list[Transform]:
    if name == "tf2_msgs/TFMessage":
        return [Transform(_ros_header(t)[0], t.header.frame_id, t.child_frame_id,
                          _xyz(t.transform.translation), _xyzw(t.transform.rotation))
                for t in m.transforms]
    items = _get(m, "transforms") if name == "foxglove.FrameTransforms" else [m]
    return [Transform(_fox_time(_get(t, "timestamp")), _get(t, "parent_frame_id"), _get(t, "child_frame_id"),
                      _xyz(_get(t, "translation")), _xyzw(_get(t, "rotation")))
            for t in items]


def _tags(m: Any, name: str) -> TagsMsg:
    return TagsMsg(_fox_time(m["timestamp"]), {str(k): str(v) for k, v in m["tags"].items()})


def _lanes2d(m: Any, name: str) -> Lanes2DMsg:
    lanes = []
    for lane in m["lanes"]:
        uv = np.asarray(lane["uv"], dtype=np.float64).reshape(-1, 2)
        if not np.isfinite(uv).all():
            raise MessageError("a detection has NaN or inf pixel coordinates")
        lanes.append(Detection2D(uv, float(lane["score"]), int(lane["category"])))
    if not m["frame_id"]:
        raise MessageError("no frame_id")
    return Lanes2DMsg(_fox_time(m["timestamp"]), str(m["frame_id"]), lanes)


_CONVERTERS = {IMAGE: _image, OCCLUDERS: _image, CALIBRATION: _calibration, TRANSFORMS: _transforms,
               LANES2D: _lanes2d, TAGS: _tags}


# --- field access shared by Foxglove protobuf objects and Foxglove JSON dicts ---------------

def _get(message: Any, name: str) -> Any:
    return message[name] if isinstance(message, dict) else getattr(message, name)


def _fox_time(t: Any) -> int:
    """google.protobuf.Timestamp or JSON {sec, nsec} -> ns."""
    if isinstance(t, dict):
        return int(t["sec"]) * NS + int(t["nsec"])
    return t.seconds * NS + t.nanos


def _fox_bytes(value: Any) -> bytes:
    return base64.b64decode(value) if isinstance(value, str) else bytes(value)


def _ros_header(m: Any) -> tuple[int, str]:
    return m.header.stamp.sec * NS + m.header.stamp.nanosec, m.header.frame_id


def _xyz(v: Any) -> tuple[float, float, float]:
    return tuple(float(v.get(k, 0.0)) if isinstance(v, dict) else float(getattr(v, k)) for k in "xyz")


def _xyzw(q: Any) -> tuple[float, float, float, float]:
    return tuple(float(q.get(k, 0.0)) if isinstance(q, dict) else float(getattr(q, k)) for k in "xyzw")


# --- images ------------------------------------------------------------------------------------

def _compressed(stamp: int, frame_id: str, fmt: str, data: bytes) -> ImageMsg:
    """A compressed image; its true format comes from its magic bytes, the ``format`` string may be loose.

    The image is decoded once here: bytes cut short or corrupt behind a valid header would
    otherwise become a good frame and fail only in training, naming no clip.
    """
    encoding = compressed_format(data)
    if encoding is None:
        if not any(name in str(fmt).lower() for name in ("jpeg", "jpg", "png")):
            raise MessageError(f"unsupported image format {fmt!r} (supported: {', '.join(COMPRESSED_ENCODINGS)})")
        raise MessageError(f"format {fmt!r}, but " + ("the bytes are neither JPEG nor PNG (no signature at their "
                                                      "start: garbage data)" if data else "the message holds no bytes"))
    try:
        width, height = compressed_size(data, encoding)
        decode_compressed(data, encoding, width, height)
    except ValueError as err:
        raise MessageError(f"garbled {encoding} image: {err}") from None
    return ImageMsg(stamp, frame_id, encoding, width, height, data)


def _raw(stamp: int, frame_id: str, encoding: str, width: int, height: int, step: int, data: bytes) -> ImageMsg:
    """A raw image, rows unpadded (the store has no row stride)."""
    if encoding not in RAW_CHANNELS:
        raise MessageError(f"unsupported image encoding {encoding!r} (supported: jpeg, png, {', '.join(RAW_CHANNELS)})")
    row = width * RAW_CHANNELS[encoding]
    step = step or row
    if step < row or len(data) < step * (height - 1) + row:
        raise MessageError(f"{encoding} image of {width}x{height} (step {step}) has only {len(data)} bytes")
    if step != row:  # drop the padding at the end of each row
        data = np.lib.stride_tricks.as_strided(np.frombuffer(data, np.uint8), (height, row), (step, 1)).tobytes()
    return ImageMsg(stamp, frame_id, encoding, int(width), int(height), data[:row * height])


# --- lanelab.Lanes3D, parsed in batches ----------------------------------------------------------

_LANES3D_SCHEMA = pa.schema([
    ("timestamp", pa.struct([("sec", pa.int64()), ("nsec", pa.int64())])),
    ("frame_id", pa.string()),
    ("lanes", pa.list_(pa.struct([
        ("track_id", pa.int64()),
        ("category", pa.int64()),
        ("points", pa.list_(pa.list_(pa.float64()))),
        ("visibility", pa.list_(pa.float64())),
    ]))),
])
_JSON_BLOCK = 1 << 22
_LANES3D_PARSE = pa_json.ParseOptions(explicit_schema=_LANES3D_SCHEMA, unexpected_field_behavior="ignore")


def parse_lanes3d(payloads: Sequence[bytes]) -> list[LanesMsg | MessageError]:
    """``lanelab.Lanes3D`` JSON payloads -> one LanesMsg each, or the MessageError that makes it unusable."""
    if not payloads:
        return []
    # JSON strings cannot hold raw line breaks, so flattening each payload to one line is safe.
    lines = b"\n".join(p.replace(b"\r", b" ").replace(b"\n", b" ") for p in payloads)
    # Arrow parses blocks of lines in parallel; a line must fit in a block.
    block_size = max(_JSON_BLOCK, 2 * max(len(p) for p in payloads))
    try:
        table = pa_json.read_json(io.BytesIO(lines), read_options=pa_json.ReadOptions(block_size=block_size),
                                  parse_options=_LANES3D_PARSE)
        if table.num_rows != len(payloads):
            raise pa.ArrowInvalid(f"{table.num_rows} rows from {len(payloads)} messages")
    except (pa.ArrowInvalid, pa.ArrowTypeError) as err:
        if len(payloads) == 1:
            return [MessageError(f"not a lanelab.Lanes3D message: {err}")]
        return [result for payload in payloads for result in parse_lanes3d([payload])]  # find the bad ones
    return _lanes_from_table(table)


def _lanes_from_table(table: pa.Table) -> list[LanesMsg | MessageError]:
    """The rows of Arrow's table of labels -> LanesMsg (or MessageError), slicing flat numpy buffers."""
    def numbers(array: pa.Array, fill: int | None = 0) -> np.ndarray:
        """Arrow values -> numpy; nulls become ``fill`` (None: NaN, for fields that must be present)."""
        return (array if fill is None else pc.fill_null(array, fill)).to_numpy(zero_copy_only=False)

    def starts(counts: np.ndarray) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    timestamp = table["timestamp"].combine_chunks()
    sec, nsec = pc.struct_field(timestamp, "sec"), pc.struct_field(timestamp, "nsec")
    stamps = numbers(pc.add(pc.multiply(sec, NS), nsec), None)
    frame_ids = table["frame_id"].to_pylist()
    lanes = table["lanes"].combine_chunks()
    structs = pc.list_flatten(lanes)
    track_ids, categories = (numbers(pc.struct_field(structs, name), None) for name in ("track_id", "category"))
    points, visibility = (pc.struct_field(structs, name) for name in ("points", "visibility"))
    num_points = numbers(pc.list_value_length(points))  # per lane
    num_visibility = numbers(pc.list_value_length(visibility))  # per lane
    num_coords = numbers(pc.list_value_length(pc.list_flatten(points)))  # per point
    xyz = numbers(pc.list_flatten(pc.list_flatten(points)), None)
    vis = numbers(pc.list_flatten(visibility), None).astype(np.float32)
    # First lane of each message, first point and visibility of each lane, first coordinate of each point.
    lane_at, point_at = starts(numbers(pc.list_value_length(lanes))), starts(num_points)
    vis_at, coord_at = starts(num_visibility), starts(num_coords)

    results: list[LanesMsg | MessageError] = []
    for i, (stamp, frame_id) in enumerate(zip(stamps, frame_ids)):
        ls = slice(lane_at[i], lane_at[i + 1])
        ps = slice(point_at[ls.start], point_at[ls.stop])
        problem = _label_problem(stamp, frame_id, track_ids[ls], categories[ls], num_points[ls], num_visibility[ls],
                                 num_coords[ps])
        if problem:
            results.append(MessageError(f"not a lanelab.Lanes3D message: {problem}"))
            continue
        results.append(LanesMsg(int(stamp), frame_id, track_ids[ls].astype(np.int64), categories[ls].astype(np.int64),
                                num_points[ls].astype(np.int64),
                                xyz[coord_at[ps.start]:coord_at[ps.stop]].reshape(-1, 3),
                                vis[vis_at[ls.start]:vis_at[ls.stop]]))
    return results


def _label_problem(stamp: float, frame_id: str | None, track_ids: np.ndarray, categories: np.ndarray,
                   num_points: np.ndarray, num_visibility: np.ndarray, num_coords: np.ndarray) -> str:
    """What makes one parsed label unusable, "" if nothing (missing values come as NaN or None)."""
    if np.isnan(stamp):
        return "no timestamp {sec, nsec}"
    if not frame_id:
        return "no frame_id"
    if np.isnan(track_ids).any() or np.isnan(categories).any():
        return "a lane has no track_id or category"
    if np.any(num_points != num_visibility):
        return "a lane's visibility does not have one value per point"
    if np.any(num_coords != 3):
        return "a point does not have 3 coordinates"
    return ""
