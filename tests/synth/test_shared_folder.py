"""Issue 37, case 9: two lanelab-synth runs into one folder. The first holds the folder's lock;
the second stops at once, naming the first's pid, before it writes synth_config.yaml or a log."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from data_ingest.synth.config import load_synth_config
from data_ingest.synth.synthesize import LOCK_NAME, synthesize
from lanelab.config_checks import ConfigError
from lanelab.folder_lock import lock_folder

TINY = ["num_logs=1", "duration_s=0.4", "fps=5", "camera.width=64", "camera.height=48", "tf_rate_hz=10",
        "preview=false"]


def test_a_second_run_into_a_folder_being_written_is_refused(tmp_path):
    out = tmp_path / "logs"
    cfg = load_synth_config([f"output_dir={out}", *TINY])
    with lock_folder(out, LOCK_NAME):  # another run, writing
        with pytest.raises(ConfigError, match=f"output_dir={out} is being written by another lanelab-synth "
                                              f"\\(pid {os.getpid()} on "):
            synthesize(cfg)
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # no config, no log, no temporary

    (out / f".synth_s0_000.mcap.{os.getpid() + 1}.partial").write_bytes(b"a killed run's half log")
    (result,) = synthesize(cfg)  # once the other is done, the folder is free; leftovers go
    assert result.summary is not None and result.path.is_file()
    assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME, "synth_config.yaml", "synth_s0_000.mcap"]


@pytest.mark.slow
def test_the_command_says_so_in_one_line(tmp_path):
    out = tmp_path / "logs"
    with lock_folder(out, LOCK_NAME):
        result = subprocess.run([sys.executable, "-m", "data_ingest.synth.cli", f"output_dir={out}", *TINY],
                                capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith(f"lanelab-synth: output_dir={out} is being written by another lanelab-synth "
                                    f"(pid {os.getpid()} on ")
    assert len(result.stderr.strip().splitlines()) == 1
