"""lanelab-synth end to end: bad options fail before anything is written; a small run writes logs and a preview."""

import subprocess
import sys

import pytest

TINY = ["duration_s=1.0", "fps=5", "camera.width=160", "camera.height=120", "tf_rate_hz=20"]


def run_synth(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "data_ingest.synth.cli", *args],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(
    "option, message",
    [
        ("world.num_lanes=-1", "world.num_lanes"),
        ("world.weather=hail", "world.weather"),
        ("camera.width=0", "camera.width"),
        ("camera.height=0", "camera.height"),
        ("encoding=rosbag", "encoding"),
        ("duration_s=-3", "duration_s"),
        ("no_such_key=1", "no_such_key"),
        ("+no_such_key=1", "no_such_key: no such option"),  # "+" adds past the struct flag
        ("+camera.no_such_key=1", "camera.no_such_key: no such option"),
        ("num_logs=many", "num_logs"),
        ("topics.lanes=", "topics.lanes is empty"),
        ("frames.ego=", "frames.ego is empty"),
        ("start_time=yesterday", "start_time='yesterday' is no ISO 8601 date and time"),
    ],
)
def test_bad_option_fails_before_writing(tmp_path, option, message):
    out = tmp_path / "logs"
    result = run_synth(f"output_dir={out}", option)
    assert result.returncode != 0
    assert message in result.stderr + result.stdout
    assert not out.exists()


@pytest.mark.slow
def test_small_run_writes_logs_preview_and_resumes(tmp_path):
    out = tmp_path / "logs"
    first = run_synth(f"output_dir={out}", "num_logs=2", "workers=2", *TINY, "--preview")
    assert first.returncode == 0, first.stderr
    logs = sorted(out.glob("*.mcap"))
    assert [p.name for p in logs] == ["synth_s0_000.mcap", "synth_s0_001.mcap"]
    assert (out / "preview.png").stat().st_size > 1000
    assert not list(out.glob(".*.partial"))
    before = {p: p.stat().st_mtime_ns for p in logs}

    again = run_synth(f"output_dir={out}", "num_logs=2", *TINY)
    assert again.returncode == 0, again.stderr
    assert "0 logs written, 2 kept" in again.stdout
    assert {p: p.stat().st_mtime_ns for p in logs} == before
