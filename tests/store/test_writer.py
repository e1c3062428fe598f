"""StoreWriter, the one update policy of the writing tools: open or refuse, keep, replace, commit."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from lanelab.store import (
    ClipEntry,
    ClipStore,
    FrameRecord,
    ManifestError,
    SourceEntry,
    StoreBusy,
    StoreRefused,
    StoreWriter,
    damaged_clips,
    file_sha256,
    read_manifest,
    write_clip,
)

OPTIONS = {"clips": {"gap_s": 0.5}, "seed": 1}


def name_of(path: str) -> str:
    return Path(path).stem


def open_writer(root: Path, options: dict = OPTIONS, **kwargs) -> StoreWriter:
    return StoreWriter(root, options, name_of, **kwargs)


def two_frames() -> list[FrameRecord]:
    """Two frames at 10 and 20 ns."""
    return [FrameRecord(t, b"x", "jpeg", 4, 2, np.eye(3), np.eye(4), np.eye(4), False) for t in (10, 20)]


def write(root: Path, clip_id: str, source: str, split: str = "train") -> ClipEntry:
    """Write a two-frame clip file; its manifest entry (no sha256 recorded)."""
    write_clip(root, clip_id, two_frames())
    return ClipEntry(clip_id, source, split, 2, 10, 20)


def commit(writer: StoreWriter, source: str, sha256: str, *clip_ids: str, split: str = "train", **kwargs) -> None:
    clips = [write(writer.root, clip_id, source, split) for clip_id in clip_ids]
    writer.commit(SourceEntry(source, sha256, 2 * len(clips)), clips, **kwargs)


def clip_files(root: Path) -> list[str]:
    return sorted(path.name for path in (root / "clips").iterdir())


def test_commits_list_sources_by_path_and_clips_by_id(tmp_path):
    writer = open_writer(tmp_path)
    assert not (tmp_path / "manifest.json").exists()
    commit(writer, "logs/b.mcap", "b1", "b_0", "b_1")
    commit(writer, "logs/a.mcap", "a1", "a_0")
    manifest = read_manifest(tmp_path)
    assert [s.path for s in manifest.sources] == ["logs/a.mcap", "logs/b.mcap"]
    assert [c.clip_id for c in manifest.clips] == ["a_0", "b_0", "b_1"]
    assert manifest.options == OPTIONS
    assert ClipStore(tmp_path).read_frames("b_1")[1].timestamp_ns == 20


def test_a_source_is_kept_only_whole_unchanged_and_not_overwritten(tmp_path):
    commit(open_writer(tmp_path), "logs/a.mcap", "a1", "a_0", "a_1", split="val")
    writer = open_writer(tmp_path)
    assert writer.kept_sha256("logs/a.mcap") == "a1"
    assert writer.kept_sha256("elsewhere/a.mcap") == "a1"  # known by name
    assert writer.kept_sha256("logs/a.mcap", "val") == "a1"
    assert writer.kept_sha256("logs/a.mcap", "train") is None
    assert writer.kept_sha256("logs/b.mcap") is None
    writer.close()
    assert open_writer(tmp_path, overwrite=True).kept_sha256("logs/a.mcap") is None
    (tmp_path / "clips" / "a_1.parquet").unlink()
    assert open_writer(tmp_path).kept_sha256("logs/a.mcap") is None


def test_a_commit_replaces_the_source_of_the_same_name_then_deletes_its_old_clips(tmp_path):
    writer = open_writer(tmp_path)
    commit(writer, "logs/a.mcap", "a1", "a_0", "a_1")
    commit(writer, "logs/b.mcap", "b1", "b_0")
    commit(writer, "moved/a.mcap", "a2", "a_1", "a_2")
    manifest = read_manifest(tmp_path)
    assert [(s.path, s.sha256) for s in manifest.sources] == [("logs/b.mcap", "b1"), ("moved/a.mcap", "a2")]
    assert [(c.clip_id, c.source) for c in manifest.clips] == [
        ("a_1", "moved/a.mcap"), ("a_2", "moved/a.mcap"), ("b_0", "logs/b.mcap")]
    assert clip_files(tmp_path) == ["a_1.parquet", "a_2.parquet", "b_0.parquet"]


def test_marks_follow_the_clips_they_were_given_to(tmp_path):
    writer = open_writer(tmp_path, marks=["no_pose"])
    commit(writer, "a", "a1", "a_0", marks=["no_pose"])
    commit(writer, "b", "b1", "b_0", marks=["no_pose"])
    assert read_manifest(tmp_path).options == {**OPTIONS, "no_pose": ["a_0", "b_0"]}
    writer.close()
    writer = open_writer(tmp_path, marks=["no_pose"])  # marks are not options: the store opens
    commit(writer, "a", "a2", "a_0")
    assert read_manifest(tmp_path).options["no_pose"] == ["b_0"]


def test_a_failed_source_leaves_no_clip_file_but_the_listed_ones(tmp_path):
    writer = open_writer(tmp_path)
    commit(writer, "a", "a1", "a_0")
    write(tmp_path, "a_1", "a")
    writer.discard(["a_0", "a_1"])
    assert clip_files(tmp_path) == ["a_0.parquet"]


def test_other_options_are_refused_unless_overwriting(tmp_path):
    commit(open_writer(tmp_path), "a", "a1", "a_0")
    other = {"clips": {"gap_s": 1.0}, "seed": 1}
    with pytest.raises(StoreRefused, match=r"other options \(clips\.gap_s: 0\.5 -> 1\.0\)"):
        open_writer(tmp_path, other)
    writer = open_writer(tmp_path, other, overwrite=True)
    assert read_manifest(tmp_path).options == OPTIONS  # nothing written before a commit
    commit(writer, "a", "a2", "a_9")
    assert read_manifest(tmp_path).options == other and clip_files(tmp_path) == ["a_9.parquet"]


def test_a_store_of_another_tool_is_refused_even_when_overwriting(tmp_path):
    commit(open_writer(tmp_path, {"made_by": "tool-a"}), "a", "a1", "a_0")
    for options in ({"made_by": "tool-b"}, {}):
        with pytest.raises(StoreRefused, match="did not make"):
            open_writer(tmp_path, options, overwrite=True)


def test_a_garbled_manifest_stops_the_writer_and_stays(tmp_path):
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(ManifestError, match="cannot read the manifest"):
        open_writer(tmp_path)
    assert (tmp_path / "manifest.json").read_text() == "{not json"


def test_overwrite_sets_a_garbled_manifest_aside_and_starts_afresh(tmp_path):
    (tmp_path / "manifest.json").write_text("{not json")
    with open_writer(tmp_path, overwrite=True) as writer:
        assert writer.set_aside == tmp_path / "manifest.json.unreadable"
        assert writer.manifest.clips == [] and not (tmp_path / "manifest.json").exists()
        commit(writer, "a", "a1", "a_0")
    assert (tmp_path / "manifest.json.unreadable").read_text() == "{not json"
    assert [clip.clip_id for clip in read_manifest(tmp_path).clips] == ["a_0"]


def test_assign_split_moves_clips_and_writes_the_manifest(tmp_path):
    with open_writer(tmp_path) as writer:
        commit(writer, "a", "a1", "a_0", "a_1", split="val")
        writer.assign_split(["a_1"], "train")
    assert [(c.clip_id, c.split) for c in read_manifest(tmp_path).clips] == [("a_0", "val"), ("a_1", "train")]


def test_a_second_writer_is_refused_until_the_first_closes(tmp_path):
    writer = open_writer(tmp_path)
    with pytest.raises(StoreBusy, match=rf"{tmp_path} is being written by another writer \(pid {os.getpid()} on "):
        open_writer(tmp_path)
    writer.close()
    with open_writer(tmp_path) as again:
        commit(again, "a", "a1", "a_0")
    assert [c.clip_id for c in read_manifest(tmp_path).clips] == ["a_0"]


def test_a_clip_that_no_longer_matches_its_sha256_is_not_kept(tmp_path):
    with open_writer(tmp_path) as writer:
        path = write_clip(tmp_path, "a_0", two_frames())
        writer.commit(SourceEntry("a", "a1", 2), [ClipEntry("a_0", "a", "train", 2, 10, 20, file_sha256(path))])
        assert writer.kept_sha256("a") == "a1"
        data = bytearray(path.read_bytes())
        data[len(data) // 2] ^= 0xFF
        path.write_bytes(bytes(data))
        assert writer.kept_sha256("a") is None
    assert damaged_clips(tmp_path) == [f"{path}: clip 'a_0' damaged: its sha256 is not the one the manifest records"]


def test_a_manifest_without_clip_hashes_still_reads(tmp_path):
    with open_writer(tmp_path) as writer:
        commit(writer, "a", "a1", "a_0")
    assert "sha256" not in (tmp_path / "manifest.json").read_text().split('"clips"')[1]
    assert read_manifest(tmp_path).clips[0].sha256 is None
    with open_writer(tmp_path) as writer:
        assert writer.kept_sha256("a") == "a1"  # not verified, not refused
    assert damaged_clips(tmp_path) == []


def test_opening_deletes_the_half_written_clips_of_a_killed_run(tmp_path):
    (tmp_path / "clips").mkdir()
    (tmp_path / "clips" / ".a_0.parquet.partial").write_bytes(b"half")
    open_writer(tmp_path).close()
    assert list((tmp_path / "clips").iterdir()) == []
