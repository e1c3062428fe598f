"""Synthetic logs ingest to stores that equal the generator's ground truth, whatever the encoding."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from ingest_helpers import ENCODINGS, START_NS, ingest_into, read_log, write_log

from lanelab.geometry import T_BASE_LANE, T_LANE_BASE
from lanelab.store import ClipStore
from lanelab.store.image_codec import decode_image

TOL = 1e-4  # metres (and unitless for rotations and K)


def stored_frames(store):
    clips = ClipStore(store)
    return [frame for clip in clips.clips for frame in clips.read_frames(clip.clip_id)]


def clip_tables(store):
    clips = ClipStore(store)
    return [pq.read_table(clips.clip_path(clip.clip_id)) for clip in clips.clips]


@pytest.mark.parametrize("labels_frame", ["base_link", "odom"])
def test_store_equals_ground_truth(tmp_path, synth_log, drive, labels_frame):
    results = ingest_into(tmp_path, synth_log("ros2", f"labels_frame={labels_frame}"))
    assert [r.status for r in results] == ["ingested"] and not results[0].dropped
    frames = stored_frames(tmp_path)
    assert [f.timestamp_ns for f in frames] == [START_NS + g.timestamp_ns for g in drive.truth]
    for f, g in zip(frames, drive.truth):
        assert (f.width, f.height, f.image_encoding) == (160, 120, "jpeg")
        np.testing.assert_allclose(f.K, drive.camera.K, atol=TOL)
        np.testing.assert_allclose(f.T_world_lane, g.T_world_base @ T_BASE_LANE.numpy(), atol=TOL)
        np.testing.assert_allclose(f.T_lane_cam, T_LANE_BASE.numpy() @ drive.camera.T_base_cam, atol=TOL)
        assert f.labeled == (g.index % 3 == 0)
        assert f.tags == g.tags
        expected = g.lanes if f.labeled else []
        assert [(lane.track_id, lane.category) for lane in f.lanes] == [(lane.track_id, lane.category)
                                                                         for lane in expected]
        for lane, true in zip(f.lanes, expected):
            assert lane.points.dtype == np.float32 and np.all(np.diff(lane.points[:, 1]) >= 0)
            np.testing.assert_allclose(lane.points, true.points, atol=TOL)
            np.testing.assert_allclose(lane.visibility, true.visibility, atol=1e-6)
    assert sum(len(f.lanes) for f in frames) > 0


def test_every_encoding_gives_the_same_store(tmp_path, synth_log):
    tables = {}
    for name in ENCODINGS:
        ingest_into(tmp_path / name, synth_log(name))
        tables[name] = clip_tables(tmp_path / name)
    reference = tables.pop("ros2")
    assert len(reference) == 1 and reference[0].num_rows == 20
    for name, other in tables.items():
        assert len(other) == len(reference), name
        assert all(a.equals(b) for a, b in zip(reference, other)), name


@pytest.mark.parametrize("encoding", ["ros2", "foxglove-protobuf"])
def test_raw_images_are_stored_as_they_came(tmp_path, synth_log, drive, encoding):
    ingest_into(tmp_path, synth_log(encoding, "image_format=raw"))
    for frame, true in zip(stored_frames(tmp_path), drive.truth):
        assert frame.image_encoding == "bgr8" and frame.image == true.image.tobytes()
        np.testing.assert_array_equal(decode_image(frame), true.image[..., ::-1])  # the drive renders BGR


CUSTOM_TOPICS = ["topics.image=/cam/img", "topics.calibration=/cam/info", "topics.tf=/pose_tf",
                 "topics.tf_static=/mount_tf", "topics.lanes=/gt/lanes3d", "topics.tags=/meta/tags"]
CUSTOM_FRAMES = ["frames.world=map", "frames.ego=chassis"]


def test_custom_topic_and_frame_names(tmp_path, synth_log):
    log = synth_log("ros2", *CUSTOM_TOPICS, *CUSTOM_FRAMES, "camera.frame_id=cam_optical", "labels_frame=odom")
    results = ingest_into(tmp_path / "custom", log, *CUSTOM_TOPICS, *CUSTOM_FRAMES)
    assert results[0].status == "ingested" and results[0].labeled == 7
    ingest_into(tmp_path / "default", synth_log("ros2", "labels_frame=odom"))
    assert clip_tables(tmp_path / "custom")[0].equals(clip_tables(tmp_path / "default")[0])

    failed = ingest_into(tmp_path / "default_names", log)[0]
    assert failed.status == "failed"
    assert "missing required topics /camera/front/image, /camera/front/camera_info, /tf" in failed.error
    assert "/cam/img (sensor_msgs/CompressedImage, 20 messages)" in failed.error


def test_clips_cut_at_max_length_and_target_rate(tmp_path, synth_log):
    log = synth_log("ros2")
    ingest_into(tmp_path / "short", log, "clips.max_length_s=0.5", "split.by=clip")
    clips = ClipStore(tmp_path / "short").clips
    assert [c.num_frames for c in clips] == [5, 5, 5, 5]
    assert all(c.last_timestamp_ns - c.first_timestamp_ns <= 0.5e9 for c in clips)
    assert [c.first_timestamp_ns - START_NS for c in clips] == [0, 500_000_000, 1_000_000_000, 1_500_000_000]

    results = ingest_into(tmp_path / "slow", log, "clips.target_fps=5")
    frames = stored_frames(tmp_path / "slow")
    assert [f.timestamp_ns - START_NS for f in frames] == [k * 200_000_000 for k in range(10)]
    assert results[0].dropped == {"left out for clips.target_fps=5.0": 10}


def test_a_label_stamped_apart_from_its_image_goes_through_the_world_frame(tmp_path, synth_log, drive):
    """Labels stamped 20 ms after their images (one /tf period): points in base_link at the label's time."""
    late = 20_000_000
    messages = []
    for m in read_log(synth_log("ros2")):
        if m.topic == "/lanes":
            label = json.loads(m.data)
            label["timestamp"]["nsec"] += late  # every stamp here is a whole 0.1 s: no carry into sec
            m = dataclasses.replace(m, data=json.dumps(label).encode())
        messages.append(m)
    ingest_into(tmp_path, write_log(tmp_path / "late_labels.mcap", messages))
    for frame, true in zip(stored_frames(tmp_path), drive.truth):
        if not frame.labeled:
            continue
        # The label's base_link points (the truth at the image time, as written) were measured at t + 20 ms.
        T_lane_base_late = np.linalg.inv(frame.T_world_lane) @ drive.pose_at(true.timestamp_ns + late)
        for lane, true_lane in zip(frame.lanes, true.lanes):
            base = true_lane.points @ T_BASE_LANE.numpy()[:3, :3].T  # lane frame -> base_link at the image
            expected = base @ T_lane_base_late[:3, :3].T + T_lane_base_late[:3, 3]
            expected = expected[np.argsort(expected[:, 1], kind="stable")]
            np.testing.assert_allclose(lane.points, expected, atol=TOL)


def test_calibration_tolerance(tmp_path, synth_log):
    messages = read_log(synth_log("ros2"))  # calibrations of frames 0-9 kept (log times lag stamps by < 30 ms)
    log = write_log(tmp_path / "half_calibrated.mcap",
                    [m for m in messages if m.topic != "/camera/front/camera_info" or m.log_time < START_NS + 950_000_000])
    assert ingest_into(tmp_path / "any", log)[0].num_frames == 20  # null: the nearest at any time
    result = ingest_into(tmp_path / "near", log, "tolerances.calibration_s=0.05")[0]
    assert result.num_frames == 10
    assert result.dropped == {"no calibration on /camera/front/camera_info within tolerances.calibration_s=0.05": 10}
