"""lanelab-ingest end to end, and its options: bad ones fail by name before anything is read."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest
from hydra.errors import ConfigCompositionException

from data_ingest.ingest.config import load_ingest_config
from data_ingest.synth.config import ConfigError
from lanelab.store import read_manifest


def run_ingest(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "data_ingest.ingest.cli", *args],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_a_bad_log_fails_alone_and_sets_the_exit_status(tmp_path, synth_log):
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(synth_log("ros2"), logs / "good.mcap")
    (logs / "empty.mcap").write_bytes(b"")
    store = tmp_path / "store"
    result = run_ingest(f"input={logs}", f"output={store}")
    assert result.returncode == 1, result.stderr
    assert f"error: {logs / 'empty.mcap'}: empty file (0 bytes)" in result.stdout
    assert "2 logs: 1 failed, 1 ingested; 20 frames ingested" in result.stdout
    assert [s.path for s in read_manifest(store).sources] == [str(logs / "good.mcap")]

    missing = run_ingest(f"input={tmp_path / 'nothing_here'}", f"output={store}")
    assert missing.returncode == 2 and "no MCAP log there" in missing.stderr


@pytest.mark.parametrize("override, error, message", [
    ("no_such_key=1", ConfigCompositionException, "no_such_key"),
    ("+no_such_key=1", ConfigError, "no_such_key: no such option"),  # "+" adds past the struct flag
    ("+clips.no_such_key=1", ConfigError, "clips.no_such_key: no such option"),
    ("tolerances.label_s=soon", ConfigCompositionException, "tolerances.label_s"),
    ("workers=0", ConfigError, "workers"),
    ("split.train=0.9", ConfigError, "split ratios"),
    ("split.by=frame", ConfigError, "split.by"),
    ("clips.target_fps=1", ConfigError, "clips.target_fps"),
    ("frames.world=", ConfigError, "frames.world"),
])
def test_bad_options_fail_by_name(override, error, message):
    with pytest.raises(error, match=message.replace(".", r"\.")):
        load_ingest_config([override])
