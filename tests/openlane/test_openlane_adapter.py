"""The OpenLane adapter on a tiny hand-made dataset: geometry, store layout, and agreement
with the official evaluator's conversion of the ground truth."""

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
from openlane_helpers import (
    FIRST_STAMP,
    INTRINSIC,
    LANES,
    TRAIN_SEGMENT,
    VAL_SEGMENT,
    adapter_config,
    stamp,
    write_tiny_openlane,
)

from data_ingest.openlane.adapter import adapt
from data_ingest.synth.config import ConfigError
from lanelab.metrics.openlane import OpenLaneConfig, evaluate, evaluate_frame
from lanelab.openlane.file_paths import FILE_PATH_TAG, file_path_of
from lanelab.openlane.write import write_prediction
from lanelab.store import CLIP_SCHEMA, ClipStore, Manifest, write_manifest


def store_frames(store, clip_id):
    return ClipStore(store).read_frames(clip_id)


def project(points, K, T_lane_cam):
    """(N, 2) pixels of lane-frame points (N, 3), in plain numpy."""
    camera = (np.linalg.inv(T_lane_cam) @ np.vstack([points.T, np.ones(len(points))]))[:3]
    return (K @ camera)[:2].T / camera[2][:, None]


def by_row(uv):
    return uv[np.argsort(uv[:, 1])]


def test_store_lanes_project_onto_the_ground_truth_pixels(tiny, store):
    for index, frame in enumerate(store_frames(store, VAL_SEGMENT)):
        gt = json.loads(tiny.json_path("validation", VAL_SEGMENT, index).read_text())
        np.testing.assert_array_equal(frame.K, INTRINSIC)
        assert [lane.category for lane in frame.lanes] == [category for _, category, _ in LANES]
        for lane, gt_lane in zip(frame.lanes, gt["lane_lines"]):
            assert np.all(np.diff(lane.points[:, 1]) > 0), "y ascending, also for a lane stored far to near"
            uv = project(lane.points.astype(np.float64), frame.K, frame.T_lane_cam)
            # the same points in any order: compare them from the top of the image down
            np.testing.assert_allclose(by_row(uv), by_row(np.array(gt_lane["uv"]).T), atol=1e-3)


def test_lanes_keep_visibility_track_ids_and_categories(store):
    frame = store_frames(store, VAL_SEGMENT)[0]
    assert [lane.track_id for lane in frame.lanes] == [-1, 11, 12]  # the curb has no track id
    for lane in frame.lanes:
        far = lane.points[:, 1] > 80.0
        assert np.all(lane.visibility[far] == 0) and np.all(lane.visibility[lane.points[:, 1] < 70.0] == 1)


def test_poses_place_static_lanes_at_the_same_world_points(tiny, store):
    for frame in store_frames(store, VAL_SEGMENT):
        for lane, world in zip(frame.lanes, tiny.world_lanes):
            points = np.vstack([lane.points.T.astype(np.float64), np.ones(len(lane.points))])
            np.testing.assert_allclose((frame.T_world_lane @ points)[:3].T, world, atol=1e-4)


def test_segment_without_pose_gets_the_identity_and_a_note(store):
    frames = store_frames(store, TRAIN_SEGMENT)
    assert all(np.array_equal(frame.T_world_lane, np.eye(4)) for frame in frames)
    assert ClipStore(store).manifest.options["clips_without_pose"] == [TRAIN_SEGMENT]


def test_store_reads_with_clip_store_and_with_pyarrow_alone(store):
    clips = {clip.clip_id: clip for clip in ClipStore(store).clips}
    assert {c: (clips[c].split, clips[c].num_frames) for c in clips} == {
        VAL_SEGMENT: ("val", 3), TRAIN_SEGMENT: ("train", 2)}
    assert clips[VAL_SEGMENT].first_timestamp_ns == FIRST_STAMP * 10
    frames = store_frames(store, VAL_SEGMENT)
    assert [f.timestamp_ns for f in frames] == [stamp(i) * 10 for i in range(3)]
    assert all(f.labeled and f.image_encoding == "jpeg" and (f.width, f.height) == (192, 128) for f in frames)

    manifest = json.loads((store / "manifest.json").read_text())
    assert (manifest["format"], manifest["version"]) == ("lanelab-clips", 1)
    table = pq.read_table(store / "clips" / f"{VAL_SEGMENT}.parquet")
    assert table.schema.names == CLIP_SCHEMA.names
    rows = table.to_pylist()
    assert rows[1]["image"][:2] == b"\xff\xd8"
    first_lane = rows[0]["lanes"][0]
    assert first_lane["category"] == 20 and len(first_lane["points"][0]) == 3
    tags = [dict(row["tags"]) for row in rows]
    assert tags[0][FILE_PATH_TAG] == f"validation/{VAL_SEGMENT}/{stamp(0)}.jpg"
    assert [t.get("curve") for t in tags] == [None, "Curve", None]
    assert [t.get("night") for t in tags] == ["Night", None, "Night"]
    assert {t["environment"] for t in tags} == {"highway"} and tags[0]["daytime"] == "night"


def test_ground_truth_against_itself_scores_one(store):
    for frame in store_frames(store, VAL_SEGMENT):
        lanes = [lane.points for lane in frame.lanes]
        visibility = [lane.visibility for lane in frame.lanes]
        categories = [lane.category for lane in frame.lanes]
        result = evaluate_frame(lanes, visibility, categories, lanes, categories,
                                pred_visibility=visibility)
        assert (result.gt_count, result.recall_tp, result.precision_tp) == (3, 3, 3)


@pytest.mark.parametrize("config", [OpenLaneConfig(), OpenLaneConfig.long_range()], ids=["official", "long_range"])
def test_predictions_from_the_store_score_perfectly_against_the_original_ground_truth(tiny, store, tmp_path, config):
    """The store's lanes, written as predictions, are the evaluator's own conversion of the GT."""
    for frame in store_frames(store, VAL_SEGMENT):
        write_prediction(tmp_path, file_path_of(frame), frame.lanes)
    scores = evaluate(tiny.annotations, tmp_path, tiny.test_list, config)
    assert (scores["gt_lanes"], scores["pred_lanes"], scores["matched"]) == (9, 9, 9)
    assert scores["f1"] == scores["recall"] == scores["precision"] == scores["category_accuracy"] == 1.0
    # Lanes reach 98 m: errors of the ranges beyond have no pair (NaN).
    errors = [scores[f"{axis}_error_{span}"] for axis in "xz" for span in ("close", "far")]
    assert max(errors) < 1e-6  # the store's float32, nothing more


def test_rerun_keeps_unchanged_segments_and_rewrites_changed_ones(tmp_path):
    data = write_tiny_openlane(tmp_path / "data")
    cfg = adapter_config(data, tmp_path / "store")
    assert [r.status for r in adapt(cfg)] == ["written", "written"]
    clip = tmp_path / "store" / "clips" / f"{VAL_SEGMENT}.parquet"
    before = clip.stat().st_mtime_ns

    assert [r.status for r in adapt(cfg)] == ["kept", "kept"]
    assert clip.stat().st_mtime_ns == before

    path = data.json_path("training", TRAIN_SEGMENT, 1)
    changed = json.loads(path.read_text())
    changed["lane_lines"][1]["category"] = 8
    path.write_text(json.dumps(changed))
    assert [r.status for r in adapt(cfg)] == ["written", "kept"]  # training comes first
    assert [lane.category for lane in store_frames(tmp_path / "store", TRAIN_SEGMENT)[1].lanes] == [20, 8, 1]
    assert len(ClipStore(tmp_path / "store").clips) == 2

    moved = adapt(adapter_config(data, tmp_path / "store", "splits.validation=test"))
    assert [r.status for r in moved] == ["kept", "written"]
    assert ClipStore(tmp_path / "store").clip(VAL_SEGMENT).split == "test"


def test_a_bad_segment_fails_naming_the_file_and_the_others_go_on(tmp_path):
    data = write_tiny_openlane(tmp_path / "data")
    bad = data.json_path("training", TRAIN_SEGMENT, 0)
    broken = json.loads(bad.read_text())
    del broken["extrinsic"]
    bad.write_text(json.dumps(broken))
    missing_image = data.images / "validation" / VAL_SEGMENT / f"{stamp(2)}.jpg"
    missing_image.unlink()

    results = {r.segment: r for r in adapt(adapter_config(data, tmp_path / "store"))}
    assert results[TRAIN_SEGMENT].status == "failed"
    assert str(bad) in results[TRAIN_SEGMENT].error and "extrinsic" in results[TRAIN_SEGMENT].error
    assert results[VAL_SEGMENT].status == "failed" and str(missing_image) in results[VAL_SEGMENT].error
    assert not (tmp_path / "store" / "clips" / f"{VAL_SEGMENT}.parquet").exists()

    shutil.copy(data.images / "validation" / VAL_SEGMENT / f"{stamp(1)}.jpg", missing_image)
    results = {r.segment: r for r in adapt(adapter_config(data, tmp_path / "store"))}
    assert results[VAL_SEGMENT].status == "written" and results[TRAIN_SEGMENT].status == "failed"
    assert [c.clip_id for c in ClipStore(tmp_path / "store").clips] == [VAL_SEGMENT]


def test_a_store_made_by_another_tool_is_refused(tiny, tmp_path):
    write_manifest(tmp_path / "store", Manifest(options={"made_by": "lanelab-ingest"}))
    with pytest.raises(ConfigError, match="did not make"):
        adapt(adapter_config(tiny, tmp_path / "store"))


@pytest.mark.parametrize("key, value, problem", [
    ("file_path", "../../../../tmp/x/rel.jpg", "'file_path' '../../../../tmp/x/rel.jpg' climbs out of its folder"),
    ("file_path", "/tmp/x/abs.jpg", "'file_path' '/tmp/x/abs.jpg' is absolute"),
    ("intrinsic", [[100.0, 0.0, 96.0], [0.0, 100.0, 64.0], [0.0, 0.0, 0.0]],
     "'intrinsic' is not a pinhole matrix: last row is [0.0, 0.0, 0.0], not [0, 0, 1]"),
    ("intrinsic", [[100.0, 0.0, 96.0], [5.0, 100.0, 64.0], [0.0, 0.0, 1.0]],
     "'intrinsic' is not a pinhole matrix: K[1][0]=5, not 0"),
    ("intrinsic", [[-100.0, 0.0, 96.0], [0.0, 100.0, 64.0], [0.0, 0.0, 1.0]],
     "'intrinsic' is not a pinhole matrix: focal lengths fx=-100, fy=100 are not both positive"),
])  # fmt: skip
def test_a_file_path_leading_out_or_a_singular_intrinsic_fails_its_segment(tmp_path, key, value, problem):
    """Issue 37, cases 1 and 4: what an annotation names is data; it is checked where it enters."""
    data = write_tiny_openlane(tmp_path / "data")
    bad = data.json_path("training", TRAIN_SEGMENT, 1)
    annotation = json.loads(bad.read_text())
    annotation[key] = value
    bad.write_text(json.dumps(annotation))
    results = {r.segment: r for r in adapt(adapter_config(data, tmp_path / "store"))}
    assert results[TRAIN_SEGMENT].status == "failed" and results[VAL_SEGMENT].status == "written"
    assert results[TRAIN_SEGMENT].error.startswith(f"{bad}: {problem}")
