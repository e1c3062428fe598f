"""lanelab-train composed through Hydra: every model x sampler runs, bad options fail by name."""

import subprocess
import sys
from pathlib import Path

import pytest
from hydra.errors import ConfigCompositionException
from tiny_store import tiny_overrides

from lanelab.config_checks import ConfigError
from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train

SAMPLERS = {"window": ["sampler=window"], "stream": ["sampler=stream", "data.num_frames=1"]}


@pytest.mark.parametrize("sampler", sorted(SAMPLERS))
@pytest.mark.parametrize("model", ["sparselanestp", "latr_baseline"])
def test_fast_dev_run(model: str, sampler: str, tiny_store: Path, tmp_path: Path) -> None:
    overrides = [f"model={model}", *SAMPLERS[sampler], "trainer.fast_dev_run=true", "test=true"]
    metrics = train(load_train_config(tiny_overrides(tiny_store, tmp_path, *overrides)))
    assert metrics["test/num_frames"] > 0
    assert (tmp_path / "metrics.json").is_file()


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("+model.net.embd_dim=32", "model.net.embd_dim"),  # a typo: no such parameter
        ("+seeed=3", "seeed"),  # Hydra adds a "+" key past the schema's struct flag
        ("+paths.log_dirr=x", "paths.log_dirr"),
        ("model.net.num_lines=many", "model.net.num_lines"),  # a wrong type
        ("+trainer.max_epoch=3", "trainer.max_epoch"),
        ("data.batch_size=2.5", "data.batch_size"),
        ("sampler.train.history=3", "sampler.train.history"),
    ],
)
def test_bad_key_fails_with_its_name(override: str, key: str, tiny_store: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_train_config(tiny_overrides(tiny_store, tmp_path, override))


@pytest.mark.parametrize(("override", "key"), [("seed=abc", "seed"), ("trainer.max_epoch=3", "trainer.max_epoch")])
def test_schema_rejects_at_composition(override: str, key: str, tiny_store: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigCompositionException, match=key):
        load_train_config(tiny_overrides(tiny_store, tmp_path, override))


def test_cli_exits_2_naming_the_key(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "lanelab.experiment.train", "experiment=tiny", "+model.net.embd_dim=32",
               f"hydra.run.dir={tmp_path}"]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert "model.net.embd_dim" in result.stderr


@pytest.mark.parametrize(("manifest", "message"), [(None, "no clip store manifest there"), ("{not json", "cannot read the manifest")])
def test_cli_exits_1_with_one_line_on_a_missing_or_broken_store(manifest: str | None, message: str, tmp_path: Path) -> None:
    store = tmp_path / "store"
    store.mkdir()
    if manifest is not None:
        (store / "manifest.json").write_text(manifest)
    command = [sys.executable, "-m", "lanelab.experiment.train", *tiny_overrides(store, tmp_path / "run"),
               f"hydra.run.dir={tmp_path / 'run'}"]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    assert result.returncode == 1
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith(f"lanelab-train: {store / 'manifest.json'}: {message}") and "Traceback" not in result.stderr
