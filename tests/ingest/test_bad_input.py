"""Every kind of bad input: a clear message naming the file, topic or frame; what can be kept is kept.

Damaged copies of a small synthetic log are made with the ``mcap`` library alone
(:mod:`ingest_helpers`), as another writer could produce them.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from ingest_helpers import START_NS, chunk_spans, ingest_into, read_log, small_config, write_log
from mcap.writer import Writer

from data_ingest.synth.mcap_writer import write_drive_log
from lanelab.store import ClipStore

IMAGE, CALIBRATION, LANES = "/camera/front/image", "/camera/front/camera_info", "/lanes"


def ingest_one(tmp_path: Path, log: Path, *overrides: str):
    (result,) = ingest_into(tmp_path / "store", log, *overrides)
    return result


def stamps(store: Path) -> list[int]:
    clips = ClipStore(store)
    return [t for clip in clips.clips for t in pq.read_table(clips.clip_path(clip.clip_id))["timestamp_ns"].to_pylist()]


def test_missing_required_topic_lists_what_the_log_has(tmp_path, synth_log):
    log = write_log(tmp_path / "no_calibration.mcap",
                    [m for m in read_log(synth_log("ros2")) if m.topic != CALIBRATION])
    result = ingest_one(tmp_path, log)
    assert result.status == "failed"
    assert str(log) in result.error and f"missing required topic {CALIBRATION}" in result.error
    assert f"{IMAGE} (sensor_msgs/CompressedImage, 20 messages)" in result.error and "/tf (" in result.error
    assert not (tmp_path / "store" / "manifest.json").exists()


def test_unknown_schema_names_topic_and_schema(tmp_path, synth_log):
    messages = [dataclasses.replace(m, schema_name="acme_msgs/msg/Frame") if m.topic == IMAGE else m
                for m in read_log(synth_log("ros2"))]
    result = ingest_one(tmp_path, write_log(tmp_path / "acme.mcap", messages))
    assert result.status == "failed"
    assert f"topic {IMAGE} has unknown schema 'acme_msgs/msg/Frame'" in result.error
    assert "sensor_msgs/CompressedImage" in result.error  # what would have been understood


def test_unknown_image_encoding_drops_those_frames(tmp_path, synth_log):
    messages, webp = [], 0
    for m in read_log(synth_log("foxglove-protobuf")):
        if m.topic == IMAGE and webp < 5:
            image = CompressedImage.FromString(m.data)
            image.format, image.data = "webp", b"RIFF\x10\x00\x00\x00WEBPVP8 "
            m, webp = dataclasses.replace(m, data=image.SerializeToString()), webp + 1
        messages.append(m)
    result = ingest_one(tmp_path, write_log(tmp_path / "webp.mcap", messages))
    assert result.status == "ingested" and result.num_frames == 15
    assert result.dropped == {"image message unusable: unsupported image format 'webp' (supported: jpeg, png)": 5}


def test_truncated_log_keeps_every_complete_message_before_the_break(tmp_path, synth_log):
    data = synth_log("ros2").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:int(len(data) * 0.6)])
    result = ingest_one(tmp_path, cut)
    assert result.status == "ingested" and 0 < result.num_frames < 20
    warning = result.warnings[0]
    assert "truncated or unreadable from byte" in warning and "recovered the" in warning and "bytes are lost" in warning
    assert stamps(tmp_path / "store") == [START_NS + k * 100_000_000 for k in range(result.num_frames)]


def test_log_cut_in_its_footer_loses_nothing(tmp_path, synth_log):
    data = synth_log("ros2").read_bytes()
    cut = tmp_path / "footless.mcap"
    cut.write_bytes(data[:-20])
    result = ingest_one(tmp_path, cut)
    assert result.status == "ingested" and result.num_frames == 20
    assert result.warnings == ["the summary section or footer is cut; every message was read"]


def test_chunk_with_bad_crc_is_skipped_and_counted(tmp_path, synth_log):
    log = synth_log("ros2")
    data = bytearray(log.read_bytes())
    spans = chunk_spans(log)
    start, length = spans[len(spans) // 2]
    data[start + length // 2] ^= 0xFF
    flipped = tmp_path / "flipped.mcap"
    flipped.write_bytes(bytes(data))
    result = ingest_one(tmp_path, flipped)
    assert result.status == "ingested" and result.num_frames < 20 and len(spans) > 2
    warning = result.warnings[0]
    assert warning.startswith("skipped 1 bad chunk(s) holding ") and f"on {IMAGE}" in warning
    assert f"chunk at bytes {start}-{start + length}" in warning


def test_nan_poses_drop_the_frames_that_need_them(tmp_path, drive):
    def pose_at(t_ns: int) -> np.ndarray:
        return np.full((4, 4), math.nan) if 500_000_000 <= t_ns <= 800_000_000 else drive.pose_at(t_ns)

    cfg = small_config()
    log = write_drive_log(tmp_path / "nan.mcap", dataclasses.replace(drive, pose_at=pose_at), cfg).path
    result = ingest_one(tmp_path, log)
    assert result.status == "ingested"
    assert result.dropped == {"ego pose odom <- base_link has NaN or inf": 4}  # images at 0.5 ... 0.8 s
    assert len(stamps(tmp_path / "store")) == 16


def test_tf_tree_that_never_connects_world_and_camera(tmp_path, synth_log):
    no_static = write_log(tmp_path / "no_static.mcap",
                          [m for m in read_log(synth_log("ros2")) if m.topic != "/tf_static"])
    result = ingest_one(tmp_path, no_static)
    assert result.status == "failed"
    assert "never connects the ego and camera frames 'base_link' and 'camera_front_optical'" in result.error
    assert "odom -> base_link (101 samples)" in result.error

    result = ingest_one(tmp_path, synth_log("ros2"), "frames.world=map")
    assert result.status == "failed" and "never connects the world and ego frames 'map' and 'base_link'" in result.error


def test_out_of_order_stamps_are_ordered_and_repeated_ones_dropped(tmp_path, synth_log):
    messages = read_log(synth_log("foxglove-protobuf"))
    images = [i for i, m in enumerate(messages) if m.topic == IMAGE]
    for a, b in zip(images[5:10], reversed(images[5:10])):  # frames 5..9 written backwards
        if a < b:
            messages[a], messages[b] = messages[b], messages[a]
    messages.append(messages[images[12]])  # frame 12 once more, at the end
    result = ingest_one(tmp_path, write_log(tmp_path / "shuffled.mcap", messages))
    assert result.status == "ingested" and result.num_frames == 20
    assert result.dropped == {"repeated image timestamp (the first image kept)": 1}
    # 9 > 8 > 7 > 6 > 5 and 19 > 12: five steps back in file order
    assert f"{IMAGE}: 5 image stamps out of order (largest step back 0.700 s); frames are ordered by stamp" \
        in result.warnings
    assert stamps(tmp_path / "store") == [START_NS + k * 100_000_000 for k in range(20)]


def test_empty_and_non_mcap_files(tmp_path):
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert ingest_one(tmp_path, empty).error == f"{empty}: empty file (0 bytes)"

    header_only = tmp_path / "header_only.mcap"
    with open(header_only, "wb") as handle:
        writer = Writer(handle)
        writer.start()
        writer.finish()
    assert ingest_one(tmp_path, header_only).error == f"{header_only}: the log has no channels and no messages"

    noise = tmp_path / "noise.mcap"
    noise.write_bytes(np.random.default_rng(0).bytes(5000))
    assert ingest_one(tmp_path, noise).error == f"{noise}: not an MCAP file (no MCAP magic at its start)"


def test_a_log_cut_inside_its_only_chunk_says_where(tmp_path, synth_log):
    one_chunk = write_log(tmp_path / "one_chunk.mcap", read_log(synth_log("ros2")), chunk_size=1 << 30)
    (start, length), = chunk_spans(one_chunk)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(one_chunk.read_bytes()[: start + length // 2])
    result = ingest_one(tmp_path, cut)
    assert result.status == "failed"
    assert result.error.startswith(f"{cut}: truncated or unreadable from byte {start} of {start + length // 2}, "
                                   "before any complete message (")
    assert result.error.endswith("): nothing to ingest")


def test_garbled_label_is_skipped_and_its_frame_kept_unlabeled(tmp_path, synth_log):
    messages = read_log(synth_log("ros2"))
    first_label = next(i for i, m in enumerate(messages) if m.topic == LANES)
    messages[first_label] = dataclasses.replace(messages[first_label], data=b'{"timestamp": {"sec": 0}, "lanes": 3}')
    result = ingest_one(tmp_path, write_log(tmp_path / "garbled.mcap", messages))
    assert result.status == "ingested" and result.num_frames == 20 and result.labeled == 6
    (warning,) = result.warnings
    assert warning.startswith(f"1 message(s) skipped on {LANES}: not a lanelab.Lanes3D message")



def test_nan_lane_points_drop_the_frame_with_a_reason(tmp_path, synth_log):
    messages, spoiled = [], False
    for m in read_log(synth_log("ros2")):
        if m.topic == LANES and not spoiled:  # the label of the first image: one coordinate missing (NaN)
            label = json.loads(m.data)
            label["lanes"][0]["points"][3][1] = None
            m, spoiled = dataclasses.replace(m, data=json.dumps(label).encode()), True
        messages.append(m)
    result = ingest_one(tmp_path, write_log(tmp_path / "nan_lane.mcap", messages))
    assert result.status == "ingested" and result.num_frames == 19
    assert result.dropped == {f"label on {LANES} has NaN or inf lane points or visibility": 1}
    assert stamps(tmp_path / "store")[0] == START_NS + 100_000_000
