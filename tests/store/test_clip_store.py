"""The clip store: frames round-trip, windows read only their row groups, pyarrow alone reads it."""

from __future__ import annotations

import json
import re

import numpy as np
import pyarrow.parquet as pq
import pytest

import lanelab.store.clip_file as clip_file
from lanelab.lanes import Lane
from lanelab.store import (
    CLIP_SCHEMA,
    ClipEntry,
    ClipStore,
    FrameRecord,
    Manifest,
    ManifestError,
    SourceEntry,
    read_manifest,
    write_clip,
    write_manifest,
)


def frame(k: int) -> FrameRecord:
    """Frame k of a test clip: lanes on every other frame (one of a single point), a pose that moves."""
    lanes = [Lane(np.arange(3 * (j + 1), dtype=np.float32).reshape(-1, 3) + k,
                  np.linspace(0, 1, j + 1, dtype=np.float32), j, track_id=10 + j)
             for j in range(3)] if k % 2 == 0 else []
    pose = np.eye(4)
    pose[:3, 3] = (k, 2.0 * k, 0.5)
    return FrameRecord(timestamp_ns=1_000 + 100 * k, image=bytes([k]) * (k + 1), image_encoding="jpeg", width=8,
                       height=6, K=np.arange(9.0).reshape(3, 3) + k, T_lane_cam=np.eye(4) * (k + 1),
                       T_world_lane=pose, labeled=k % 2 == 0, lanes=lanes, tags={"weather": "sun", "k": str(k)})


def assert_same(a: FrameRecord, b: FrameRecord) -> None:
    for name in ("timestamp_ns", "image", "image_encoding", "width", "height", "labeled", "tags"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("K", "T_lane_cam", "T_world_lane"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert [(lane.track_id, lane.category) for lane in a.lanes] == [(lane.track_id, lane.category) for lane in b.lanes]
    for x, y in zip(a.lanes, b.lanes):
        np.testing.assert_array_equal(x.points, y.points)
        np.testing.assert_array_equal(x.visibility, y.visibility)


@pytest.fixture
def store(tmp_path):
    frames = [frame(k) for k in range(21)]
    write_clip(tmp_path, "c0", frames)
    write_manifest(tmp_path, Manifest([SourceEntry("log.mcap", "ab" * 32, 21)],
                                      [ClipEntry("c0", "log.mcap", "val", 21, 1_000, 3_000)]))
    return tmp_path, frames


def test_windows_round_trip_reading_only_their_row_groups(store, monkeypatch):
    root, frames = store
    calls = []
    monkeypatch.setattr(clip_file, "open", lambda *a: calls.append("open") or open(*a), raising=False)
    read_row_groups = pq.ParquetFile.read_row_groups
    monkeypatch.setattr(pq.ParquetFile, "read_row_groups",
                        lambda self, groups, **kw: calls.append(list(groups)) or read_row_groups(self, groups, **kw))
    clips = ClipStore(root)
    assert clips.clips_in("val") == clips.clips and clips.clips_in("train") == []
    for start, stop, groups in [(0, 21, [0, 1, 2]), (3, 7, [0]), (6, 10, [0, 1]), (20, 21, [2]), (8, 16, [1])]:
        calls.clear()
        window = clips.read_frames("c0", start, stop)
        assert calls == ["open", groups]
        assert len(window) == stop - start
        for a, b in zip(window, frames[start:stop]):
            assert_same(a, b)
    with pytest.raises(IndexError):
        clips.read_frames("c0", 20, 22)
    with pytest.raises(KeyError, match="no clip 'c9'"):
        clips.read_frames("c9")


def test_labels_are_read_without_the_images(store, monkeypatch):
    root, frames = store
    read_table = pq.read_table
    columns = []
    monkeypatch.setattr(pq, "read_table", lambda path, **kw: columns.append(kw.get("columns")) or read_table(path, **kw))
    labels = ClipStore(root).read_labels("c0")
    assert columns == [["labeled", "lanes"]]
    assert [labeled for labeled, _ in labels] == [f.labeled for f in frames]
    for (_, lanes), original in zip(labels, frames):
        assert_same(FrameRecord(**{**vars(original), "lanes": lanes}), original)


def test_timelines_and_tags_are_read_without_the_images(store, monkeypatch):
    root, frames = store
    read_table = pq.read_table
    columns = []
    monkeypatch.setattr(pq, "read_table", lambda path, **kw: columns.append(kw.get("columns")) or read_table(path, **kw))
    clips = ClipStore(root)
    timestamps, labeled = clips.read_timeline("c0")
    assert timestamps.dtype == np.int64 and timestamps.tolist() == [f.timestamp_ns for f in frames]
    assert labeled.dtype == bool and labeled.tolist() == [f.labeled for f in frames]
    assert clips.read_tags("c0") == [(f.timestamp_ns, f.tags) for f in frames]
    assert columns == [["labeled", "timestamp_ns"], ["timestamp_ns", "tags"]]


def test_readable_with_pyarrow_and_json_alone(store):
    root, frames = store
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["format"] == "lanelab-clips" and manifest["version"] == 1
    assert manifest["sources"] == [{"path": "log.mcap", "sha256": "ab" * 32, "num_frames": 21}]
    assert manifest["clips"][0] == {"clip_id": "c0", "source": "log.mcap", "split": "val", "num_frames": 21,
                                    "first_timestamp_ns": 1_000, "last_timestamp_ns": 3_000}
    table = pq.read_table(root / "clips" / "c0.parquet")
    assert table.schema.equals(CLIP_SCHEMA) and pq.ParquetFile(root / "clips" / "c0.parquet").num_row_groups == 3
    row = table.slice(4, 1).to_pylist()[0]
    assert row["timestamp_ns"] == 1_400 and row["image"] == bytes([4]) * 5 and row["labeled"]
    assert row["K"] == (np.arange(9.0) + 4).tolist() and len(row["T_world_lane"]) == 16
    assert row["lanes"][1] == {"track_id": 11, "category": 1, "points": [[4, 5, 6], [7, 8, 9]],
                               "visibility": [0.0, 1.0]}
    assert dict(row["tags"]) == {"k": "4", "weather": "sun"}


def test_writes_are_atomic_and_in_time_order(store):
    root, frames = store
    before = (root / "clips" / "c0.parquet").read_bytes()
    with pytest.raises(ValueError, match="strictly increasing"):
        write_clip(root, "c0", [frames[0], *frames[2:], frames[1]])
    with pytest.raises(ValueError, match="no frames"):
        write_clip(root, "c0", [])
    assert (root / "clips" / "c0.parquet").read_bytes() == before
    assert sorted(p.name for p in (root / "clips").iterdir()) == ["c0.parquet"]


def test_manifest_entries_of_other_writers_may_hold_more_keys(tmp_path):
    """The contract fixes the names of a source's and a clip's fields, not that there are no
    others: a store written by another tool with extra per-entry keys reads, the extras ignored."""
    clip = {"clip_id": "c0", "source": "log.mcap", "split": "test", "num_frames": 3,
            "first_timestamp_ns": 0, "last_timestamp_ns": 200, "camera": "front", "weather": "fog"}
    source = {"path": "log.mcap", "sha256": "ab" * 32, "num_frames": 3, "writer": "other-tool 2.1"}
    (tmp_path / "manifest.json").write_text(json.dumps(
        {"format": "lanelab-clips", "version": 1, "sources": [source], "clips": [clip], "producer": "x"}))
    manifest = read_manifest(tmp_path)
    assert manifest.sources == [SourceEntry("log.mcap", "ab" * 32, 3)]
    assert manifest.clips == [ClipEntry("c0", "log.mcap", "test", 3, 0, 200)]


@pytest.mark.parametrize("content, message", [
    (None, "no clip store manifest"),
    ("{not json", "cannot read the manifest"),
    ('{"format": "something-else", "version": 1}', "not a lanelab-clips manifest"),
    ('{"format": "lanelab-clips", "version": 2, "sources": [], "clips": []}', "version 2 is not supported"),
    ('{"format": "lanelab-clips", "version": 1, "sources": []}', "malformed manifest"),
    ('{"format": "lanelab-clips", "version": 1, "sources": [["log.mcap"]], "clips": []}', "malformed manifest"),
    ('{"format": "lanelab-clips", "version": 1, "sources": [], "clips": [{"clip_id": "c0"}]}', "malformed manifest"),
    # A clip id names a file of the store (issue 37): data never leads out of it.
    *((f'{{"format": "lanelab-clips", "version": 1, "sources": [], "clips": [{{"clip_id": "{clip_id}", '
       f'"source": "s", "split": "test", "num_frames": 1, "first_timestamp_ns": 0, "last_timestamp_ns": 0}}]}}',
       re.escape(f"clip id '{clip_id}' {problem}: refused"))
      for clip_id, problem in [("../../x", "holds a path separator"), ("/tmp/x", "holds a path separator"),
                               ("..", "climbs out of its folder ('..')")]),
])
def test_bad_manifests_are_named(tmp_path, content, message):
    if content is not None:
        (tmp_path / "manifest.json").write_text(content)
    with pytest.raises(ManifestError, match=message) as error:
        read_manifest(tmp_path)
    assert str(tmp_path / "manifest.json") in str(error.value)
