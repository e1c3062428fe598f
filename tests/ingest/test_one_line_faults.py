"""Issue 37, case 10 (ingest): faults that got a traceback or a misleading line. An output that
cannot be written is one line (exit status 2); a log of channels without a message says it is
empty; a re-ingest that re-writes a missing or damaged clip says so."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from ingest_helpers import ingest_into, read_log, write_log
from mcap.writer import Writer

from lanelab.store import read_manifest

CLI = [sys.executable, "-m", "data_ingest.ingest.cli"]


def run_ingest(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120)


@pytest.mark.slow
@pytest.mark.parametrize("blocked", ["a file in the way", "read-only folder"])
def test_an_output_that_cannot_be_written_is_one_line(tmp_path, synth_log, blocked):
    if blocked == "a file in the way":
        (tmp_path / "file").write_text("not a folder")
        output, reason = tmp_path / "file" / "store", "Not a directory"
    else:
        if os.geteuid() == 0:
            pytest.skip("root writes into read-only folders")
        (tmp_path / "ro").mkdir(mode=0o555)
        output, reason = tmp_path / "ro" / "store", "Permission denied"
    result = run_ingest(f"input={synth_log('ros2')}", f"output={output}")
    assert result.returncode == 2
    assert result.stderr.strip() == f"lanelab-ingest: output={output}: cannot write the store there ({reason})"


def test_a_log_of_channels_without_messages_says_it_is_empty(tmp_path):
    empty = tmp_path / "empty.mcap"
    with open(empty, "wb") as handle:
        writer = Writer(handle)
        writer.start()
        schema = writer.register_schema("foxglove.CompressedImage", "jsonschema", b"{}")
        for topic in ("/camera/front/image", "/camera/front/camera_info", "/tf"):
            writer.register_channel(topic, "json", schema)
        writer.finish()
    (result,) = ingest_into(tmp_path / "store", empty)
    assert result.status == "failed"
    assert result.error == (f"{empty}: the log is empty: its 3 channel(s) (/camera/front/camera_info, "
                            "/camera/front/image, /tf) hold no message")


@pytest.mark.parametrize("fault", ["missing", "damaged"])
def test_a_reingest_that_rewrites_a_clip_says_so(tmp_path, synth_log, fault):
    store, log = tmp_path / "store", write_log(tmp_path / "log.mcap", read_log(synth_log("ros2")))
    ingest_into(store, log)
    (clip,) = read_manifest(store).clips
    path = store / "clips" / f"{clip.clip_id}.parquet"
    if fault == "missing":
        path.unlink()
    else:
        path.write_bytes(path.read_bytes()[:-100] + bytes(100))
    (result,) = ingest_into(store, log)
    assert result.status == "ingested"
    assert result.warnings[0].startswith(f"re-written: the store's clip(s) of this log were missing or damaged "
                                         f"({clip.clip_id} {fault}")
    (again,) = ingest_into(store, log)
    assert again.status == "unchanged" and not again.warnings
