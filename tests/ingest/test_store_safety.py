"""Runs that must lose nothing: concurrent writers, kill -9 and Ctrl-C of a run with workers,
and clip files damaged after they were written."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from ingest_helpers import ingest_into

from data_ingest.ingest.ingest import verify
from lanelab.store import ClipFileError, ClipStore, file_sha256, read_manifest

CLI = [sys.executable, "-m", "data_ingest.ingest.cli"]
MANY = 120  # copies of the small log: a workers=2 run of them lasts several seconds


def start_ingest(*args: str) -> subprocess.Popen:
    """lanelab-ingest in its own process group (as a shell runs it), its output captured, with
    Ctrl-C's default action even where the tests run with SIGINT ignored (a background job of a
    non-interactive shell, nohup), which the child would inherit."""
    return subprocess.Popen([*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_default_sigint)


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def wait_for(condition, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"no {what} after {timeout_s} s")
        time.sleep(0.02)


def children(pid: int) -> set[int]:
    """The pids of the processes whose parent is ``pid`` (from /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.add(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.fixture
def many_logs(tmp_path, synth_log) -> Path:
    folder = tmp_path / "many"
    folder.mkdir()
    for index in range(MANY):
        os.link(synth_log("ros2"), folder / f"log{index:03d}.mcap")
    return folder


@pytest.mark.slow
def test_an_ingest_into_a_store_being_written_is_refused_naming_the_writer(tmp_path, synth_log):
    store = tmp_path / "store"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from lanelab.store import StoreWriter; "
                               f"w = StoreWriter({str(store)!r}, {{}}, str); print('held', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        result = subprocess.run([*CLI, f"input={synth_log('ros2')}", f"output={store}"], capture_output=True,
                                text=True, timeout=120)
    finally:
        holder.kill()
        holder.wait()
    assert result.returncode == 2
    assert result.stderr.startswith(f"lanelab-ingest: {store} is being written by another writer "
                                    f"(pid {holder.pid} on ")
    assert len(result.stderr.splitlines()) == 1
    assert not (store / "manifest.json").exists()


@pytest.mark.slow
def test_two_concurrent_ingests_never_lose_a_log(tmp_path, synth_log):
    store = tmp_path / "store"
    runs = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        for index in range(4):
            os.link(synth_log("ros2"), tmp_path / name / f"{name}{index}.mcap")
        runs.append((tmp_path / name, start_ingest(f"input={tmp_path / name}", f"output={store}")))
    listed: set[Path] = set()
    for folder, run in runs:
        _, stderr = run.communicate(timeout=120)
        assert run.returncode in (0, 2), stderr
        if run.returncode == 2:
            assert "is being written by another writer (pid " in stderr
        else:
            listed.add(folder)
    assert listed, "neither run ingested"
    sources = {Path(source.path).parent for source in read_manifest(store).sources}
    assert sources == listed
    assert len(read_manifest(store).sources) == 4 * len(listed)


@pytest.mark.slow
def test_kill_9_of_a_run_kills_its_workers(tmp_path, many_logs):
    run = start_ingest(f"input={many_logs}", f"output={tmp_path / 'store'}", "workers=2")
    workers: set[int] = set()
    try:
        def two_workers() -> bool:
            workers.update(children(run.pid))
            return len(workers) >= 2

        wait_for(two_workers, 60, "worker processes")
        run.kill()
        run.wait()
        deadline = time.monotonic() + 5
        while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [pid for pid in workers if alive(pid)]
    finally:
        for pid in workers:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


@pytest.mark.slow
def test_ctrl_c_records_the_finished_logs_and_exits_with_one_line(tmp_path, many_logs):
    store = tmp_path / "store"
    run = start_ingest(f"input={many_logs}", f"output={store}", "workers=2")
    wait_for(lambda: (store / "manifest.json").exists(), 60, "log recorded")
    workers = children(run.pid)
    os.killpg(run.pid, signal.SIGINT)
    _, stderr = run.communicate(timeout=60)
    recorded = len(read_manifest(store).sources)
    assert run.returncode == 130
    assert stderr.splitlines() == [
        f"lanelab-ingest: interrupted: {recorded} log(s) ingested into {store} by this run are recorded; "
        "run the same command again to resume with the rest"]
    assert 0 < recorded < MANY
    assert not [pid for pid in workers if alive(pid)]
    listed = {clip.clip_id for clip in read_manifest(store).clips}
    assert listed <= {path.stem for path in (store / "clips").glob("*.parquet")}


@pytest.mark.slow
def test_a_damaged_clip_is_named_by_the_reader_and_verify_and_rewritten_by_a_reingest(tmp_path, synth_log):
    store = tmp_path / "store"
    ingest_into(store, synth_log("ros2"))
    (clip,) = read_manifest(store).clips
    path = store / "clips" / f"{clip.clip_id}.parquet"
    assert clip.sha256 == file_sha256(path)
    flip_a_byte_of_the_lane_points(path)

    with pytest.raises(ClipFileError, match=f"^{path}: damaged clip file"):
        ClipStore(store).read_labels(clip.clip_id)
    with pytest.raises(ClipFileError, match=f"^{path}: damaged clip file"):
        ClipStore(store).read_frames(clip.clip_id)
    assert verify(str(store)) == 1
    result = subprocess.run([*CLI, f"output={store}", "verify=true"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1
    assert result.stdout.splitlines() == [
        f"lanelab-ingest: {path}: clip {clip.clip_id!r} damaged: its sha256 is not the one the manifest records",
        f"lanelab-ingest: {store}: 1 of 1 clip(s) missing or damaged; ingest their logs again to re-write them"]

    assert [r.status for r in ingest_into(store, synth_log("ros2"))] == ["ingested"]
    assert file_sha256(path) == clip.sha256
    assert len(ClipStore(store).read_labels(clip.clip_id)) == clip.num_frames
    assert verify(str(store)) == 0


def flip_a_byte_of_the_lane_points(path: Path) -> None:
    """Invert a byte in the middle of the first row group's lane points (a data page, past its header)."""
    metadata = pq.ParquetFile(path).metadata
    column = next(metadata.row_group(0).column(i) for i in range(metadata.num_columns)
                  if metadata.row_group(0).column(i).path_in_schema.startswith("lanes.list.element.points"))
    at = column.data_page_offset + column.total_compressed_size - 8
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))
