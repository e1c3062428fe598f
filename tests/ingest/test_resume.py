"""Re-running is a no-op, an interrupted run resumes, a changed log or option replaces what it must."""

from __future__ import annotations

import shutil

import pytest
from ingest_helpers import ingest_into

import data_ingest.ingest.ingest as ingest_module
from data_ingest.synth.config import ConfigError
from lanelab.store import ClipStore, read_manifest
from lanelab.store.lock import lock_path


@pytest.fixture
def logs(tmp_path, synth_log):
    """A folder of two logs: a.mcap (ROS 2) and b.mcap (Foxglove)."""
    folder = tmp_path / "logs"
    folder.mkdir()
    shutil.copy(synth_log("ros2"), folder / "a.mcap")
    shutil.copy(synth_log("foxglove-protobuf"), folder / "b.mcap")
    return folder


def files(store):
    """The store's files and their mtimes, but the writers' lock (which names each run)."""
    return {path: path.stat().st_mtime_ns for path in store.rglob("*") if path.is_file() and path != lock_path(store)}


def test_rerun_on_unchanged_logs_changes_nothing(tmp_path, logs):
    store = tmp_path / "store"
    assert [r.status for r in ingest_into(store, logs)] == ["ingested", "ingested"]
    before = files(store)
    assert [r.status for r in ingest_into(store, logs)] == ["unchanged", "unchanged"]
    assert files(store) == before


def test_interrupted_run_resumes(tmp_path, logs, monkeypatch):
    store = tmp_path / "store"
    real = ingest_module.ingest_log

    def interrupted_at_b(path, *args, **kwargs):
        if path.name == "b.mcap":
            raise KeyboardInterrupt
        return real(path, *args, **kwargs)

    monkeypatch.setattr(ingest_module, "ingest_log", interrupted_at_b)
    with pytest.raises(KeyboardInterrupt):
        ingest_into(store, logs)
    assert [source.path for source in read_manifest(store).sources] == [str(logs / "a.mcap")]
    assert not list(store.rglob(".*.partial"))

    monkeypatch.setattr(ingest_module, "ingest_log", real)
    assert [r.status for r in ingest_into(store, logs)] == ["unchanged", "ingested"]
    assert len(ClipStore(store).clips) == 2


def test_changed_log_replaces_its_clips(tmp_path, logs, synth_log):
    store = tmp_path / "store"
    ingest_into(store, logs / "a.mcap")
    (old,) = ClipStore(store).clips
    shutil.copy(synth_log("ros2", "image_format=png"), logs / "a.mcap")
    assert [r.status for r in ingest_into(store, logs / "a.mcap")] == ["ingested"]
    (new,) = ClipStore(store).clips
    assert new.clip_id != old.clip_id and new.split == old.split
    assert [p.name for p in (store / "clips").iterdir()] == [f"{new.clip_id}.parquet"]
    assert read_manifest(store).sources[0].sha256 == ingest_module.file_sha256(logs / "a.mcap")


def test_other_options_need_overwrite(tmp_path, logs):
    store = tmp_path / "store"
    ingest_into(store, logs)
    with pytest.raises(ConfigError, match=r"clips\.max_length_s: 20\.0 -> 1\.0"):
        ingest_into(store, logs, "clips.max_length_s=1.0")
    results = ingest_into(store, logs, "clips.max_length_s=1.0", "overwrite=true")
    assert [r.status for r in results] == ["ingested", "ingested"]
    clips = ClipStore(store).clips
    assert len(clips) == 4 and len(list((store / "clips").iterdir())) == 4
    assert read_manifest(store).options["clips"]["max_length_s"] == 1.0


def test_workers_give_the_same_store(tmp_path, logs):
    ingest_into(tmp_path / "one", logs)
    results = ingest_into(tmp_path / "two", logs, "workers=2")
    assert sorted(r.status for r in results) == ["ingested", "ingested"]
    assert read_manifest(tmp_path / "one").clips == read_manifest(tmp_path / "two").clips


def test_logs_with_the_same_name_clash(tmp_path, logs):
    (logs / "again").mkdir()
    shutil.copy(logs / "a.mcap", logs / "again" / "a.mcap")
    results = ingest_into(tmp_path / "store", logs)
    assert [r.status for r in results] == ["ingested", "failed", "ingested"]  # a, again/a, b
    assert results[1].error == f"{logs / 'again' / 'a.mcap'}: has the same name as {logs / 'a.mcap'}; " \
                               "a store knows logs by name: rename one"


def test_a_log_that_fails_while_writing_leaves_no_clip_file(tmp_path, logs, monkeypatch):
    store = tmp_path / "store"
    real = ingest_module.write_clip

    def fails_at_the_second_clip(root, clip_id, frames):
        if clip_id.endswith("_001"):
            raise OSError("disk full")
        return real(root, clip_id, frames)

    monkeypatch.setattr(ingest_module, "write_clip", fails_at_the_second_clip)
    results = ingest_into(store, logs / "a.mcap", "clips.max_length_s=1.0")
    assert [r.status for r in results] == ["failed"] and "disk full" in results[0].error
    assert list((store / "clips").iterdir()) == []
