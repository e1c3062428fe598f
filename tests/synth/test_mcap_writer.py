"""Drive logs written by ``write_drive_log``, read back only with the ``mcap`` reader and its
ROS 2 / protobuf decoders (JSON with ``json.loads``), as any MCAP consumer would."""

from __future__ import annotations

import base64
import hashlib
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from data_ingest.synth.config import start_time_ns
from data_ingest.synth.mcap_writer import MAX_LAG_NS, write_drive_log

NS = 1_000_000_000
ENCODINGS = {
    "ros2": ["encoding=ros2"],
    "foxglove-protobuf": ["encoding=foxglove", "foxglove_schema=protobuf"],
    "foxglove-json": ["encoding=foxglove", "foxglove_schema=json"],
}
SENSOR_SCHEMAS = {  # (schema name, schema encoding, message encoding) per role
    "ros2": {"tf": ("tf2_msgs/msg/TFMessage", "ros2msg", "cdr"),
             "image": ("sensor_msgs/msg/CompressedImage", "ros2msg", "cdr"),
             "raw": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
             "calibration": ("sensor_msgs/msg/CameraInfo", "ros2msg", "cdr")},
    "foxglove-protobuf": {"tf": ("foxglove.FrameTransforms", "protobuf", "protobuf"),
                          "image": ("foxglove.CompressedImage", "protobuf", "protobuf"),
                          "raw": ("foxglove.RawImage", "protobuf", "protobuf"),
                          "calibration": ("foxglove.CameraCalibration", "protobuf", "protobuf")},
    "foxglove-json": {"tf": ("foxglove.FrameTransforms", "jsonschema", "json"),
                      "image": ("foxglove.CompressedImage", "jsonschema", "json"),
                      "raw": ("foxglove.RawImage", "jsonschema", "json"),
                      "calibration": ("foxglove.CameraCalibration", "jsonschema", "json")},
}
LANELAB_SCHEMAS = {"/lanes": "lanelab.Lanes3D", "/lanes2d": "lanelab.Lanes2D", "/tags": "lanelab.Tags"}


@pytest.fixture
def write(tmp_path, synth_config, make_drive):
    """``write(*overrides, name=..., **kwargs) -> (LogSummary, drive, cfg)`` into tmp_path."""

    def write_log(*overrides: str, name: str = "drive.mcap", **kwargs):
        cfg = synth_config(*overrides)
        drive = make_drive(cfg)
        return write_drive_log(tmp_path / name, drive, cfg, **kwargs), drive, cfg

    return write_log


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- reading: plain mcap reader, the libraries' decoders, and encoding-neutral views --------

def read_messages(path: Path) -> dict[str, list[tuple[Any, Any]]]:
    """topic -> [(mcap Message record, decoded message)] in file order."""
    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[Ros2DecoderFactory(), ProtobufDecoderFactory()])
        topics = {c.topic: c.message_encoding for c in reader.get_summary().channels.values()}
        binary = [t for t, enc in topics.items() if enc != "json"]
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=binary, log_time_order=False):
            out[channel.topic].append((message, decoded))
        for _, channel, message in reader.iter_messages(topics=[t for t in topics if t not in binary],
                                                        log_time_order=False):
            out[channel.topic].append((message, json.loads(message.data)))
    return out


def get(message: Any, name: str) -> Any:
    """A field of a decoded ROS 2 / protobuf object or of a JSON dict."""
    return message[name] if isinstance(message, dict) else getattr(message, name)


def stamp_ns(message: Any) -> int:
    """Sensor time: ROS ``header.stamp`` or Foxglove/lanelab ``timestamp``."""
    if not isinstance(message, dict) and hasattr(message, "header"):
        return message.header.stamp.sec * NS + message.header.stamp.nanosec
    t = get(message, "timestamp")
    return t["sec"] * NS + t["nsec"] if isinstance(t, dict) else t.seconds * NS + t.nanos


def frame_id(message: Any) -> str:
    return message.header.frame_id if hasattr(message, "header") else get(message, "frame_id")


def data_bytes(message: Any) -> bytes:
    data = get(message, "data")
    return base64.b64decode(data) if isinstance(data, str) else bytes(data)


def transforms(message: Any) -> list[tuple]:
    """(stamp, parent, child, translation xyz, rotation xyzw) of a TFMessage / FrameTransforms."""
    out = []
    for tf in get(message, "transforms"):
        if hasattr(tf, "header"):  # ROS 2
            parent, transform = tf.header.frame_id, tf.transform
        else:
            parent, transform = get(tf, "parent_frame_id"), tf
        translation = tuple(float(get(get(transform, "translation"), k)) for k in "xyz")
        rotation = tuple(float(get(get(transform, "rotation"), k)) for k in "xyzw")
        out.append((stamp_ns(tf), parent, get(tf, "child_frame_id"), translation, rotation))
    return out


def calibration(message: Any) -> dict[str, Any]:
    ros = hasattr(message, "header")
    return {"stamp": stamp_ns(message), "frame_id": frame_id(message), "width": get(message, "width"),
            "height": get(message, "height"), "model": get(message, "distortion_model"),
            **{k: [float(v) for v in get(message, k.lower() if ros else k)] for k in "DKRP"}}


def image(message: Any) -> dict[str, Any]:
    fields = ("format",) if has(message, "format") else ("width", "height", "encoding", "step")
    return {"stamp": stamp_ns(message), "frame_id": frame_id(message), "data": data_bytes(message),
            **{k: get(message, k) for k in fields}}


def has(message: Any, name: str) -> bool:
    return name in message if isinstance(message, dict) else hasattr(message, name)


def content(path: Path) -> dict[str, list]:
    """Everything a log says, in a form that does not depend on its encoding."""
    messages = read_messages(path)
    return {
        "tf_static": [transforms(m) for _, m in messages["/tf_static"]],
        "tf": [transforms(m) for _, m in messages["/tf"]],
        "images": [image(m) for _, m in messages["/camera/front/image"]],
        "occluders": [image(m) for _, m in messages["/camera/front/occluders"]],
        "calibration": [calibration(m) for _, m in messages["/camera/front/camera_info"]],
        **{topic: [m for _, m in messages[topic]] for topic in LANELAB_SCHEMAS},
    }


JSON_TYPES = {"object": dict, "array": list, "string": str, "integer": int, "number": (int, float), "boolean": bool}


def assert_conforms(value: Any, schema: dict, where: str = "$") -> None:
    """``value`` has the JSON schema's types, and every property it names (enough for our schemas)."""
    assert isinstance(value, JSON_TYPES[schema["type"]]), f"{where}: {type(value).__name__} is no {schema['type']}"
    if schema["type"] == "object":
        properties = schema.get("properties", {})
        for key, item in value.items():
            assert key in properties or "additionalProperties" in schema, f"{where}.{key} is not in the schema"
            assert_conforms(item, properties.get(key) or schema["additionalProperties"], f"{where}.{key}")
        required = set(schema.get("required", properties))  # without "required": every property, as our schemas mean
        assert required <= set(value), f"{where}: misses {required - set(value)}"
    if schema["type"] == "array":
        for i, item in enumerate(value):
            assert_conforms(item, schema["items"], f"{where}[{i}]")


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def pose(translation, rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = quaternion_matrix(rotation), translation
    return T


# --- tests -----------------------------------------------------------------------------------

@pytest.mark.parametrize("encoding", ENCODINGS)
def test_channels_schemas_counts_and_metadata(write, encoding):
    calls = []
    summary, drive, cfg = write(*ENCODINGS[encoding], progress=calls.append)
    num_frames = round(cfg.duration_s * cfg.fps)
    assert summary.num_frames == num_frames == len(calls) and set(calls) == {1}

    with open(summary.path, "rb") as f:
        reader = make_reader(f)
        header, mcap_summary = reader.get_header(), reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert header.profile == ("ros2" if encoding == "ros2" else "")
    channels = {c.topic: c for c in mcap_summary.channels.values()}
    expected = {"/tf": SENSOR_SCHEMAS[encoding]["tf"], "/tf_static": SENSOR_SCHEMAS[encoding]["tf"],
                "/camera/front/image": SENSOR_SCHEMAS[encoding]["image"],
                "/camera/front/camera_info": SENSOR_SCHEMAS[encoding]["calibration"],
                "/camera/front/occluders": SENSOR_SCHEMAS[encoding]["image"],
                **{topic: (name, "jsonschema", "json") for topic, name in LANELAB_SCHEMAS.items()}}
    assert set(channels) == set(expected)
    for topic, (name, schema_encoding, message_encoding) in expected.items():
        schema = mcap_summary.schemas[channels[topic].schema_id]
        assert (schema.name, schema.encoding, channels[topic].message_encoding) == (name, schema_encoding,
                                                                                   message_encoding), topic
        if schema_encoding == "jsonschema":  # every JSON message conforms to its channel's schema
            for _, message in read_messages(summary.path)[topic]:
                assert_conforms(message, json.loads(schema.data), topic)

    counts = {channels_topic: mcap_summary.statistics.channel_message_counts[c.id]
              for channels_topic, c in channels.items()}
    assert counts == summary.message_counts
    assert counts == {
        "/tf_static": 1,
        "/tf": round(cfg.duration_s * cfg.tf_rate_hz) + 1,  # both ends of [0, duration]
        "/camera/front/image": num_frames,
        "/camera/front/camera_info": num_frames,
        "/camera/front/occluders": num_frames,
        "/lanes": math.ceil(num_frames / cfg.label_every),
        "/lanes2d": num_frames,
        "/tags": num_frames,
    }
    assert summary.bytes == summary.path.stat().st_size and summary.duration_s == cfg.duration_s
    meta = metadata["lanelab.synth"]
    assert meta["seed"] == str(cfg.seed)
    assert {k.removeprefix("scenario."): v for k, v in meta.items() if k.startswith("scenario.")} == drive.scenario


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_stamps_are_sensor_times_and_log_times_lag_them(write, encoding):
    summary, drive, cfg = write(*ENCODINGS[encoding])
    messages = read_messages(summary.path)
    for topic, pairs in messages.items():
        for record, message in pairs:
            stamps = [t[0] for t in transforms(message)] if "tf" in topic else [stamp_ns(message)]
            for stamp in stamps:
                assert stamp <= record.log_time <= stamp + MAX_LAG_NS, topic
            assert record.publish_time == record.log_time
    start = start_time_ns(cfg, 0)  # 2026-03-02T09:00:00Z: a date a user's tools show as one
    assert start == 1_772_442_000 * NS
    frame_times = [start + frame.timestamp_ns for frame in drive.frames()]
    for topic in ("/camera/front/image", "/camera/front/camera_info", "/camera/front/occluders", "/lanes2d", "/tags"):
        assert [stamp_ns(m) for _, m in messages[topic]] == frame_times, topic
    assert [stamp_ns(m) for _, m in messages["/lanes"]] == frame_times[:: cfg.label_every]
    tf_period = round(NS / cfg.tf_rate_hz)
    tf_stamps = [transforms(m)[0][0] for _, m in messages["/tf"]]
    assert sorted(tf_stamps) == list(range(start, start + drive.duration_ns + 1, tf_period))
    assert tf_stamps != sorted(tf_stamps)  # the lags vary enough to reorder sensor times
    with open(summary.path, "rb") as f:  # but the file itself is in log-time order
        log_times = [record.log_time for _, _, record in make_reader(f).iter_messages(log_time_order=False)]
    assert log_times == sorted(log_times)


def test_encodings_carry_the_same_content(write):
    logs = {name: write(*overrides, name=f"{name}.mcap")
            for name, overrides in ENCODINGS.items()}
    contents = {name: content(summary.path) for name, (summary, _, _) in logs.items()}
    reference = contents["ros2"]
    for name, other in contents.items():
        for key in reference:
            assert other[key] == reference[key], f"{name}: {key} differs from ros2"

    _, drive, cfg = logs["ros2"]
    camera, frames = drive.camera, list(drive.frames())
    (mount,) = reference["tf_static"]
    (_, base, body, t0, q0), (_, body2, optical, t1, q1) = mount
    assert (base, body, body2, optical) == ("base_link", "camera_front", "camera_front", camera.frame_id)
    np.testing.assert_allclose(pose(t0, q0) @ pose(t1, q1), camera.T_base_cam, atol=1e-12)
    np.testing.assert_allclose(quaternion_matrix(q1), [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-15)
    for (stamp, parent, child, translation, rotation), in reference["tf"]:
        assert (parent, child) == ("odom", "base_link")
        np.testing.assert_allclose(pose(translation, rotation), drive.pose_at(stamp - start_time_ns(cfg, 0)), atol=1e-12)
    for calib in reference["calibration"]:
        assert (calib["frame_id"], calib["width"], calib["height"], calib["model"]) == (
            camera.frame_id, camera.width, camera.height, "plumb_bob")
        np.testing.assert_array_equal(np.reshape(calib["K"], (3, 3)), camera.K)
        np.testing.assert_array_equal(np.reshape(calib["P"], (3, 4)), np.hstack([camera.K, np.zeros((3, 1))]))
        assert calib["D"] == [0.0] * 5 and calib["R"] == np.eye(3).ravel().tolist()
    for frame, img, mask, lanes2d, tags in zip(frames, reference["images"], reference["occluders"],
                                               reference["/lanes2d"], reference["/tags"], strict=True):
        assert (mask["format"], mask["frame_id"]) == ("png", camera.frame_id)  # lossless: exactly the mask
        np.testing.assert_array_equal(cv2.imdecode(np.frombuffer(mask["data"], np.uint8), cv2.IMREAD_GRAYSCALE) > 0,
                                      frame.occluders)
        assert (img["format"], img["frame_id"]) == ("jpeg", camera.frame_id)
        decoded = cv2.imdecode(np.frombuffer(img["data"], np.uint8), cv2.IMREAD_COLOR)
        assert np.abs(decoded.astype(int) - frame.image).mean() < 6  # JPEG at quality 90 of a noisy render
        assert lanes2d["frame_id"] == camera.frame_id
        assert len(lanes2d["lanes"]) == len(frame.lanes2d)
        for written, lane in zip(lanes2d["lanes"], frame.lanes2d):
            np.testing.assert_array_equal(np.asarray(written["uv"], np.float32), lane.uv)
            assert (written["score"], written["category"]) == (pytest.approx(lane.score), lane.category)
        assert tags["tags"] == frame.tags


@pytest.mark.parametrize("labels_frame", ["base_link", "odom"])
def test_labels_round_trip_to_the_lane_frame(write, labels_frame):
    summary, drive, cfg = write(f"labels_frame={labels_frame}")
    labels = [m for _, m in read_messages(summary.path)["/lanes"]]
    frames = [f for f in drive.frames() if f.index % cfg.label_every == 0]
    assert len(labels) == len(frames) > 1
    for label, frame in zip(labels, frames):
        assert label["frame_id"] == labels_frame
        # Independent of the writer's geometry code: inverse pose, then x_L = -y_b, y_L = x_b.
        T_base_from_label = np.linalg.inv(drive.pose_at(stamp_ns(label) - start_time_ns(cfg, 0))) if labels_frame == "odom" else np.eye(4)
        assert [(lane["track_id"], lane["category"]) for lane in label["lanes"]] == [
            (lane.track_id, lane.category) for lane in frame.lanes]
        for written, lane in zip(label["lanes"], frame.lanes):
            p = np.asarray(written["points"]) @ T_base_from_label[:3, :3].T + T_base_from_label[:3, 3]
            np.testing.assert_allclose(np.stack([-p[:, 1], p[:, 0], p[:, 2]], -1), lane.points, rtol=0, atol=1e-6)
            np.testing.assert_array_equal(np.asarray(written["visibility"], np.float32), lane.visibility)


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_raw_images_decode_to_the_exact_array(write, encoding):
    summary, drive, _ = write(*ENCODINGS[encoding], "image_format=raw")
    with open(summary.path, "rb") as f:
        reader = make_reader(f)
        channel = next(c for c in reader.get_summary().channels.values() if c.topic == "/camera/front/image")
        assert reader.get_summary().schemas[channel.schema_id].name == SENSOR_SCHEMAS[encoding]["raw"][0]
    images = [image(m) for _, m in read_messages(summary.path)["/camera/front/image"]]
    for frame, img in zip(drive.frames(), images, strict=True):
        h, w = frame.image.shape[:2]
        assert (img["width"], img["height"], img["encoding"], img["step"]) == (w, h, "bgr8", 3 * w)
        np.testing.assert_array_equal(np.frombuffer(img["data"], np.uint8).reshape(h, w, 3), frame.image)


def test_png_images_are_lossless(write):
    summary, drive, _ = write("image_format=png")
    images = [image(m) for _, m in read_messages(summary.path)["/camera/front/image"]]
    for frame, img in zip(drive.frames(), images, strict=True):
        assert img["format"] == "png"
        np.testing.assert_array_equal(cv2.imdecode(np.frombuffer(img["data"], np.uint8), cv2.IMREAD_COLOR),
                                      frame.image)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_compressions_are_readable_and_writes_are_deterministic(write, compression):
    first, _, _ = write(f"compression={compression}", "chunk_size=65536", name="a.mcap")
    second, _, _ = write(f"compression={compression}", "chunk_size=65536", name="b.mcap")
    assert sha256(first.path) == sha256(second.path)
    other_log, _, _ = write(f"compression={compression}", "chunk_size=65536",
                            name="c.mcap", log_index=1)
    assert sha256(other_log.path) != sha256(first.path)  # another log of the run lags differently
    with open(first.path, "rb") as f:
        chunks = list(make_reader(f).get_summary().chunk_indexes)
    assert len(chunks) > 1 and {c.compression for c in chunks} == {"" if compression == "none" else compression}
    reference, _, _ = write(name="reference.mcap")
    assert content(first.path) == content(reference.path)


class Failing:
    """A drive whose frames() raises ``error`` after ``after`` frames."""

    def __init__(self, drive, error: BaseException, after: int = 5) -> None:
        self._drive, self._error, self._after = drive, error, after

    def __getattr__(self, name: str):
        return getattr(self._drive, name)

    def frames(self):
        for frame in self._drive.frames():
            if frame.index == self._after:
                raise self._error
            yield frame


@pytest.mark.parametrize("error", [RuntimeError("renderer crashed"), KeyboardInterrupt()], ids=["error", "ctrl-c"])
def test_an_interrupted_write_leaves_no_file(tmp_path, synth_config, make_drive, error):
    cfg = synth_config()
    with pytest.raises(type(error)):
        write_drive_log(tmp_path / "drive.mcap", Failing(make_drive(cfg), error), cfg)
    assert list(tmp_path.iterdir()) == []


def test_a_failed_rewrite_keeps_the_existing_log(tmp_path, write):
    good, drive, cfg = write()
    before = sha256(good.path)
    with pytest.raises(RuntimeError):
        write_drive_log(good.path, Failing(drive, RuntimeError("disk full")), cfg)
    assert sha256(good.path) == before
    assert [p.name for p in tmp_path.iterdir()] == ["drive.mcap"]
