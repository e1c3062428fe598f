"""The ROS 2 encoder serializes with ``mcap_ros2._dynamic.serialize_dynamic``, a private function
(mcap_ros2's public Writer owns its MCAP writer, so a file that also holds JSON channels cannot
use it). These tests check the messages it writes decode with mcap_ros2's public decoder to what
went in, and that lanelab pins mcap-ros2-support to the range where that was checked."""

from __future__ import annotations

from importlib.metadata import requires, version

import numpy as np
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from packaging.requirements import Requirement

from data_ingest.synth.encoders import (
    CALIBRATION,
    COMPRESSED_IMAGE,
    RAW_IMAGE,
    TRANSFORMS,
    Ros2Encoder,
    StampedTransform,
)
from data_ingest.synth.frame import CameraModel

T_NS = 1_700_000_123_456_789_012


def decode(encoder: Ros2Encoder, role: str, data: bytes):
    schema = encoder.schema(role)
    record = Schema(id=1, name=schema.name, encoding=schema.encoding, data=schema.data)
    return DecoderFactory().decoder_for(encoder.message_encoding, record)(data)


def test_transforms_decode_to_what_went_in():
    encoder = Ros2Encoder()
    tfs = [StampedTransform(T_NS, "odom", "base_link", (1.5, -2.25, 0.125), (0.0, 0.0, 0.6, 0.8)),
           StampedTransform(T_NS + 7, "base_link", "camera_front", (2.0, 0.0, 1.5), (0.5, -0.5, 0.5, -0.5))]
    message = decode(encoder, TRANSFORMS, encoder.transforms(tfs))
    assert len(message.transforms) == 2
    for written, tf in zip(message.transforms, tfs):
        assert divmod(tf.stamp_ns, 10**9) == (written.header.stamp.sec, written.header.stamp.nanosec)
        assert (written.header.frame_id, written.child_frame_id) == (tf.parent, tf.child)
        t, q = written.transform.translation, written.transform.rotation
        assert (t.x, t.y, t.z) == tf.translation and (q.x, q.y, q.z, q.w) == tf.rotation


def test_images_and_calibration_decode_to_what_went_in():
    encoder = Ros2Encoder()
    compressed = decode(encoder, COMPRESSED_IMAGE, encoder.compressed_image(T_NS, "cam", b"\xff\xd8jpeg", "jpeg"))
    assert (compressed.header.frame_id, compressed.format, bytes(compressed.data)) == ("cam", "jpeg", b"\xff\xd8jpeg")

    image = np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    raw = decode(encoder, RAW_IMAGE, encoder.raw_image(T_NS, "cam", image))
    assert (raw.height, raw.width, raw.encoding, raw.step, raw.is_bigendian) == (5, 7, "bgr8", 21, 0)
    np.testing.assert_array_equal(np.frombuffer(bytes(raw.data), np.uint8).reshape(5, 7, 3), image)

    K = np.array([[500.0, 0.0, 320.5], [0.0, 501.0, 240.25], [0.0, 0.0, 1.0]])
    camera = CameraModel(K, 640, 480, np.eye(4), "camera_front_optical")
    info = decode(encoder, CALIBRATION, encoder.calibration(T_NS, camera))
    assert (info.header.frame_id, info.width, info.height, info.distortion_model) == (
        "camera_front_optical", 640, 480, "plumb_bob")
    np.testing.assert_array_equal(np.reshape(info.k, (3, 3)), K)
    np.testing.assert_array_equal(np.reshape(info.p, (3, 4)), np.hstack([K, np.zeros((3, 1))]))
    assert list(info.d) == [0.0] * 5 and list(info.r) == np.eye(3).ravel().tolist()


def test_mcap_ros2_is_pinned_to_the_checked_range():
    (pin,) = [r for r in map(Requirement, requires("lanelab")) if r.name == "mcap-ros2-support"]  # as installed
    assert any(spec.operator in ("<", "<=", "==", "~=") for spec in pin.specifier), \
        f"{pin}: no upper bound, a release that moves the private module would install untested"
    assert pin.specifier.contains(version("mcap-ros2-support")), f"installed mcap-ros2-support is outside {pin}"
