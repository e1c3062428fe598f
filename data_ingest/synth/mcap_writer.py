"""Write a synthetic drive as an MCAP drive log (DESIGN.md, "Drive-log contract").

One pass over the drive's camera frames writes, on the topics of ``cfg.topics``:

- ``/tf_static`` once: the camera mount as base_link -> camera body -> optical frame;
- ``/tf`` at ``cfg.tf_rate_hz``: the ego pose odom -> base_link, faster than the camera,
  so a reader has to interpolate it at image times;
- per frame: the image, its calibration, its occluder mask (a PNG, white where a vehicle
  or a roadside object shows), ``/lanes2d`` and ``/tags``, and ``/lanes`` on every
  ``cfg.label_every``-th frame.

Sensor messages come from the encoder of ``cfg.encoding`` (:mod:`encoders`); the lanelab
JSON channels (:mod:`lanelab_msgs`) are the same in every encoding. Like a real recorder,
each message is logged a little after its sensor time (a seeded 0-30 ms lag), so readers
must use header stamps, never log times. Equal inputs give byte-identical files, written
atomically.
"""

from __future__ import annotations

import heapq
import random
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import BinaryIO, Callable, Iterator, Protocol

import cv2
import numpy as np
import torch
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType
from mcap.writer import Writer as McapWriter

import lanelab
from data_ingest.contract import LANES2D_TYPE, LANES3D_TYPE, TAGS_TYPE
from data_ingest.synth import lanelab_msgs
from data_ingest.synth.config import SynthConfig, start_time_ns
from data_ingest.synth.encoders import (
    CALIBRATION,
    COMPRESSED_IMAGE,
    RAW_IMAGE,
    TRANSFORMS,
    MessageEncoder,
    Schema,
    StampedTransform,
    make_encoder,
)
from data_ingest.synth.foxglove_json import dumps
from data_ingest.synth.frame import CameraModel, SynthFrame
from lanelab.atomic_file import atomic_output
from lanelab.geometry import T_BASE_LANE, compose, invert, rotation_to_quaternion, transform_points
from lanelab.lanes import Lane

METADATA_NAME = "lanelab.synth"
MAX_LAG_NS = 30_000_000  # log time - sensor time is drawn from [0, MAX_LAG_NS]
_END_OF_TIME = 2**63 - 1  # the largest int64 log time
COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}

# T_body_optical: the camera's optical axes (OpenCV: x right, y down, z forward) in its body
# frame (x forward, y left, z up): optical z = body x, optical x = -body y, optical y = -body z.
T_BODY_OPTICAL = torch.tensor(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
    dtype=torch.float64,
)


class DriveSource(Protocol):
    """What the writer needs of a drive (``drive.SyntheticDrive`` or a test's fake)."""

    camera: CameraModel
    duration_ns: int
    scenario: dict[str, str]  # environment / daytime / weather of the whole log

    def pose_at(self, t_ns: int) -> np.ndarray:
        """Ego pose T_odom_base (4, 4) at sensor time ``t_ns`` in [0, duration_ns]."""
        ...

    def frames(self) -> Iterator[SynthFrame]:
        """Camera frames in time order."""
        ...


@dataclass(frozen=True)
class LogSummary:
    """What :func:`write_drive_log` wrote."""

    path: Path
    message_counts: dict[str, int]  # per topic, every channel listed
    num_frames: int
    duration_s: float
    bytes: int


def write_drive_log(
    path: Path,
    drive: DriveSource,
    cfg: SynthConfig,
    progress: Callable[[int], None] | None = None,
    log_index: int | None = None,
) -> LogSummary:
    """Write ``drive`` as an MCAP file at ``path``; return what was written.

    ``progress(1)`` is called after each camera frame (so ``tqdm.update`` fits).
    ``log_index`` (the log's number in a multi-log run) seeds the log-time lags together
    with ``cfg.seed`` and is recorded in the metadata. The file appears under ``path`` only
    once complete; any exception (Ctrl-C included) leaves ``path`` as it was.
    """
    path = Path(path)
    encoder = make_encoder(cfg.encoding, cfg.foxglove_schema)
    with atomic_output(path) as tmp, open(tmp, "wb") as stream:
        log = _Recorder(stream, cfg, encoder.profile, lag_seed=f"{cfg.seed}/{log_index}")
        log.add_metadata(METADATA_NAME, _metadata(drive, cfg, log_index))
        num_frames = _write_drive(log, encoder, drive, cfg, progress, start_time_ns(cfg, log_index or 0))
        log.finish()
    return LogSummary(
        path=path,
        message_counts=dict(log.counts),
        num_frames=num_frames,
        duration_s=drive.duration_ns / 1e9,
        bytes=path.stat().st_size,
    )


def _metadata(drive: DriveSource, cfg: SynthConfig, log_index: int | None) -> dict[str, str]:
    """How the log was made; nothing that depends on when, so reruns give equal bytes."""
    meta = {
        "generator": "lanelab-synth",
        "lanelab_version": lanelab.__version__,
        "seed": str(cfg.seed),
        "encoding": cfg.encoding if cfg.encoding == "ros2" else f"{cfg.encoding}-{cfg.foxglove_schema}",
    }
    if log_index is not None:
        meta["log_index"] = str(log_index)
    meta.update({f"scenario.{key}": str(value) for key, value in sorted(drive.scenario.items())})
    return meta


@dataclass(order=True)
class _Pending:
    log_time: int
    order: int  # ties keep publication order
    topic: str = field(compare=False)
    data: bytes = field(compare=False)


class _Recorder:
    """The MCAP file being written: one channel per topic, messages in log-time order.

    Messages are published in sensor-time order and logged after a lag; they wait in a
    heap until no later publication can be logged before them (see :meth:`release`).
    """

    def __init__(self, stream: BinaryIO, cfg: SynthConfig, profile: str, lag_seed: str) -> None:
        self._mcap = McapWriter(stream, chunk_size=cfg.chunk_size, compression=COMPRESSION[cfg.compression])
        self._mcap.start(profile=profile, library=f"lanelab-synth/{lanelab.__version__} {LIBRARY_IDENTIFIER}")
        self._schema_ids: dict[Schema, int] = {}
        self._channel_ids: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self._lag = random.Random(f"lanelab.synth.lag/{lag_seed}")  # str seeds are hashed stably
        self._pending: list[_Pending] = []
        self._published = 0

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._mcap.add_metadata(name, data)

    def add_channel(self, topic: str, schema: Schema, message_encoding: str) -> None:
        if schema not in self._schema_ids:  # /tf and /tf_static share one schema record
            self._schema_ids[schema] = self._mcap.register_schema(schema.name, schema.encoding, schema.data)
        self._channel_ids[topic] = self._mcap.register_channel(topic, message_encoding, self._schema_ids[schema])
        self.counts[topic] = 0

    def publish(self, topic: str, t_ns: int, data: bytes) -> None:
        """Queue a message stamped with sensor time ``t_ns``; it is logged at t_ns + lag."""
        log_time = t_ns + self._lag.randint(0, MAX_LAG_NS)
        heapq.heappush(self._pending, _Pending(log_time, self._published, topic, data))
        self._published += 1

    def release(self, t_ns: int) -> None:
        """Write the queued messages logged by ``t_ns``: later ones are stamped, so logged, after it."""
        while self._pending and self._pending[0].log_time <= t_ns:
            message = heapq.heappop(self._pending)
            self._mcap.add_message(
                channel_id=self._channel_ids[message.topic],
                log_time=message.log_time,
                publish_time=message.log_time,
                sequence=self.counts[message.topic],
                data=message.data,
            )
            self.counts[message.topic] += 1

    def finish(self) -> None:
        self.release(_END_OF_TIME)
        self._mcap.finish()


def _write_drive(
    log: _Recorder,
    encoder: MessageEncoder,
    drive: DriveSource,
    cfg: SynthConfig,
    progress: Callable[[int], None] | None,
    start_ns: int,
) -> int:
    """Publish every message of ``drive``, its time 0 at sensor time start_ns; return the number
    of camera frames."""
    topics, camera = cfg.topics, drive.camera
    _add_channels(log, encoder, cfg)
    log.publish(topics.tf_static, start_ns, encoder.transforms(camera_mount(camera, cfg.frames.ego, stamp_ns=start_ns)))
    ego_poses = deque(ego_transforms(drive, cfg, start_ns))
    num_frames = 0
    for frame in drive.frames():
        t = start_ns + frame.timestamp_ns
        while ego_poses and ego_poses[0].stamp_ns <= t:
            log.publish(topics.tf, ego_poses[0].stamp_ns, encoder.transforms([ego_poses.popleft()]))
        _publish_frame(log, encoder, frame, t, camera, cfg)
        log.release(t)
        num_frames += 1
        if progress is not None:
            progress(1)
    for pose in ego_poses:
        log.publish(topics.tf, pose.stamp_ns, encoder.transforms([pose]))
    return num_frames


def _add_channels(log: _Recorder, encoder: MessageEncoder, cfg: SynthConfig) -> None:
    """Every channel, up front and in a fixed order: a topic without messages still shows."""
    topics = cfg.topics
    image_role = RAW_IMAGE if cfg.image_format == "raw" else COMPRESSED_IMAGE
    for topic, role in ((topics.tf_static, TRANSFORMS), (topics.tf, TRANSFORMS),
                        (topics.image, image_role), (topics.calibration, CALIBRATION),
                        (topics.occluders, COMPRESSED_IMAGE)):
        log.add_channel(topic, encoder.schema(role), encoder.message_encoding)
    for topic, name in ((topics.lanes, LANES3D_TYPE), (topics.lanes2d, LANES2D_TYPE), (topics.tags, TAGS_TYPE)):
        schema = Schema(name, SchemaEncoding.JSONSchema, dumps(lanelab_msgs.SCHEMAS[name]))
        log.add_channel(topic, schema, MessageEncoding.JSON)


def _publish_frame(log: _Recorder, encoder: MessageEncoder, frame: SynthFrame, t: int, camera: CameraModel,
                   cfg: SynthConfig) -> None:
    """The image, calibration, 2D lanes, tags and (every label_every-th frame) 3D lanes of a frame,
    stamped t (its sensor time)."""
    topics = cfg.topics
    if cfg.image_format == "raw":
        log.publish(topics.image, t, encoder.raw_image(t, camera.frame_id, frame.image))
    else:
        data = encode_image(frame.image, cfg.image_format, cfg.jpeg_quality)
        log.publish(topics.image, t, encoder.compressed_image(t, camera.frame_id, data, cfg.image_format))
    log.publish(topics.calibration, t, encoder.calibration(t, camera))
    if frame.occluders is not None:
        mask = encode_image(frame.occluders.astype(np.uint8) * 255, "png", cfg.jpeg_quality)
        log.publish(topics.occluders, t, encoder.compressed_image(t, camera.frame_id, mask, "png"))
    if frame.index % cfg.label_every == 0:
        frame_id, lanes = labels_in(frame, cfg)
        log.publish(topics.lanes, t, dumps(lanelab_msgs.lanes3d(t, frame_id, lanes)))
    log.publish(topics.lanes2d, t, dumps(lanelab_msgs.lanes2d(t, camera.frame_id, frame.lanes2d)))
    log.publish(topics.tags, t, dumps(lanelab_msgs.tags(t, frame.tags)))


def encode_image(image: np.ndarray, image_format: str, jpeg_quality: int) -> bytes:
    """(H, W, 3) uint8 BGR or (H, W) gray image -> JPEG or PNG file bytes."""
    ext, params = {"jpeg": (".jpg", [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality]), "png": (".png", [])}[image_format]
    ok, buffer = cv2.imencode(ext, image, params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {image.shape} image as {image_format}")
    return buffer.tobytes()


def _stamped(stamp_ns: int, parent: str, child: str, T: torch.Tensor) -> StampedTransform:
    """A (4, 4) parent <- child transform as translation + quaternion (x, y, z, w)."""
    return StampedTransform(stamp_ns, parent, child, tuple(T[:3, 3].tolist()),
                            tuple(rotation_to_quaternion(T[:3, :3]).tolist()))


def body_frame(optical_frame: str) -> str:
    """The camera's body frame beside its optical frame: "camera_front_optical" -> "camera_front"."""
    return optical_frame.removesuffix("_optical") if optical_frame.endswith("_optical") else f"{optical_frame}_body"


def camera_mount(camera: CameraModel, ego_frame: str, stamp_ns: int) -> list[StampedTransform]:
    """ego -> camera body -> optical frame, as ROS drivers publish a camera mount.

    The composition of the two equals ``camera.T_base_cam``.
    """
    body = body_frame(camera.frame_id)
    T_base_body = compose(torch.as_tensor(camera.T_base_cam, dtype=torch.float64), invert(T_BODY_OPTICAL))
    return [
        _stamped(stamp_ns, ego_frame, body, T_base_body),
        _stamped(stamp_ns, body, camera.frame_id, T_BODY_OPTICAL),
    ]


def ego_transforms(drive: DriveSource, cfg: SynthConfig, start_ns: int) -> list[StampedTransform]:
    """world <- ego at ``cfg.tf_rate_hz`` over the drive's [0, duration], both ends included,
    stamped start_ns later (sensor time)."""
    count = int(drive.duration_ns * cfg.tf_rate_hz // 1e9) + 1
    stamps = [round(k * 1e9 / cfg.tf_rate_hz) for k in range(count)]
    poses = torch.as_tensor(np.stack([drive.pose_at(t) for t in stamps]), dtype=torch.float64)
    translations = poses[:, :3, 3].tolist()
    rotations = rotation_to_quaternion(poses[:, :3, :3]).tolist()  # one batched call, not one per stamp
    return [
        StampedTransform(start_ns + t, cfg.frames.world, cfg.frames.ego, tuple(translation), tuple(rotation))
        for t, translation, rotation in zip(stamps, translations, rotations)
    ]


def labels_in(frame: SynthFrame, cfg: SynthConfig) -> tuple[str, list[Lane]]:
    """``frame.lanes`` (lane frame) re-expressed in ``cfg.labels_frame``: (frame_id, lanes)."""
    if cfg.labels_frame == "base_link":
        frame_id, T = cfg.frames.ego, T_BASE_LANE
    else:
        frame_id, T = cfg.frames.world, compose(torch.as_tensor(frame.T_world_base, dtype=torch.float64), T_BASE_LANE)
    lanes = [
        replace(lane, points=transform_points(T, torch.as_tensor(lane.points, dtype=torch.float64)).numpy())
        for lane in frame.lanes
    ]
    return frame_id, lanes
