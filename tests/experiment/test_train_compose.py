"""lanelab-train composed through Hydra: every model x sampler runs, bad options fail by name."""

import dataclasses
import shutil
import subprocess
import sys
from pathlib import Path
from unittest.mock import patch

import pytest
from hydra.errors import ConfigCompositionException
from hydra.utils import instantiate
from tiny_store import tiny_overrides

from lanelab.config_checks import ConfigError
from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train
from lanelab.store import DataError, read_manifest, write_manifest

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


@pytest.mark.slow
def test_cli_exits_2_naming_the_key(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "lanelab.experiment.train", "experiment=tiny", "+model.net.embd_dim=32",
               f"hydra.run.dir={tmp_path}"]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert "model.net.embd_dim" in result.stderr


@pytest.mark.slow
@pytest.mark.parametrize(("manifest", "message"), [(None, "no clip store manifest there"), ("{not json", "cannot read the manifest")])
def test_cli_exits_2_with_one_line_on_a_missing_or_broken_store(manifest: str | None, message: str, tmp_path: Path) -> None:
    store = tmp_path / "store"
    store.mkdir()
    if manifest is not None:
        (store / "manifest.json").write_text(manifest)
    command = [sys.executable, "-m", "lanelab.experiment.train", *tiny_overrides(store, tmp_path / "run"),
               f"hydra.run.dir={tmp_path / 'run'}"]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith(f"lanelab-train: {store / 'manifest.json'}: {message}")
    assert len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "run" / "checkpoints").exists()  # nothing built


def store_with_splits(tiny_store: Path, root: Path, split: str) -> Path:
    """The tiny store's clips, all in one split."""
    manifest = read_manifest(tiny_store)
    manifest.clips = [dataclasses.replace(clip, split=split) for clip in manifest.clips]
    write_manifest(root, manifest)
    (root / "clips").symlink_to(tiny_store / "clips")
    return root


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["test=true"], r"split 'train' has no clips \(clips per split: train 0, val 4, test 0\); ingest with "
                        r"split\.by=clip"),
        (["train=false", "test=true", "ckpt_path=x.ckpt"], r"split 'test' has no clips"),
        (["data.splits.train=val", "data.num_frames=50"], r"cannot draw the train samples from split 'val': .*num_frames=50 needs 49"),
        (["data.splits.train=val", "data.num_frames=0"], r"num_frames=0: a sample needs at least one frame"),
    ],
)
def test_a_store_that_cannot_feed_the_run_is_named_before_the_model_is_built(
    overrides: list[str], message: str, tiny_store: Path, tmp_path: Path
) -> None:
    store = store_with_splits(tiny_store, tmp_path / "store", "val")
    cfg = load_train_config(tiny_overrides(store, tmp_path / "run", *overrides))
    with pytest.raises(DataError, match=message), patch("lanelab.experiment.build.instantiate", wraps=instantiate) as built:
        train(cfg)
    assert [call.args[0] for call in built.call_args_list] == [cfg.data]  # the datamodule alone


@pytest.mark.slow
def test_a_clip_damaged_under_a_loader_worker_is_one_line_and_exit_1(tiny_store: Path, tmp_path: Path) -> None:
    """The checksums pass the store at the start; a clip read by a DataLoader worker then fails its
    page checksum: one line naming the file (PyTorch wraps a worker's error with its traceback)."""
    store = tmp_path / "store"
    shutil.copytree(tiny_store, store)
    clip = sorted((store / "clips").glob("*.parquet"))[0]
    data = bytearray(clip.read_bytes())
    data[len(data) // 3] ^= 0xFF
    clip.write_bytes(bytes(data))
    command = [sys.executable, "-m", "lanelab.experiment.train", *tiny_overrides(store, tmp_path / "run"),
               "data.num_workers=2", f"hydra.run.dir={tmp_path / 'run'}"]  # fmt: skip
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=300)
    assert result.returncode == 1
    assert result.stderr.splitlines()[-1].startswith(f"lanelab-train: {clip}: damaged clip file (OSError: ")
    assert "Traceback" not in result.stderr
