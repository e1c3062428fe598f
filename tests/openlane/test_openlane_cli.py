"""lanelab-openlane end to end: bad options fail by name before writing; a run adapts and resumes."""

import subprocess
import sys

import pytest

from data_ingest.openlane.config import ConfigError, load_openlane_config


def run_openlane(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "data_ingest.openlane.cli", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_run_adapts_then_keeps(tiny, tmp_path):
    args = [f"annotations={tiny.annotations}", f"images={tiny.images}", f"output={tmp_path / 'store'}",
            f"scenario_lists={tiny.scenario_lists}"]
    first = run_openlane(*args)
    assert first.returncode == 0, first.stderr
    assert "2 segments: 2 written; 5 frames" in first.stdout
    assert "1 of 2 segments have no pose" in first.stdout
    again = run_openlane(*args)
    assert again.returncode == 0 and "2 segments: 2 kept" in again.stdout


@pytest.mark.parametrize("option, message", [("no_such_key=1", "no_such_key"), ("splits.validation=holdout", "splits.validation")])
def test_bad_option_fails_by_name_before_writing(tiny, tmp_path, option, message):
    result = run_openlane(f"annotations={tiny.annotations}", f"images={tiny.images}",
                          f"output={tmp_path / 'store'}", option)
    assert result.returncode != 0 and message in result.stderr + result.stdout
    assert not (tmp_path / "store").exists()


def test_missing_folders_are_named(tiny, tmp_path):
    with pytest.raises(ConfigError, match="images="):
        load_openlane_config([f"annotations={tiny.annotations}", f"images={tmp_path / 'none'}"])
    missing = run_openlane(f"images={tiny.images}")
    assert missing.returncode == 2 and "missing option annotations" in missing.stderr
