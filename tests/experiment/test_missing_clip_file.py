"""A clip file deleted from a store stops lanelab-train and lanelab-eval with one line naming the
file and saying that the store should be re-ingested (status 1), not a traceback."""

import shutil
from pathlib import Path

import pytest
from train_command import run, train_command

from lanelab.evaluation.config import load_eval_config
from lanelab.experiment import eval_cli
from lanelab.store import ClipFileError, clip_path


def store_without(tiny_store: Path, clip_id: str, folder: Path) -> tuple[Path, Path]:
    store = shutil.copytree(tiny_store, folder / "store")
    missing = clip_path(store, clip_id)
    missing.unlink()
    return store, missing


@pytest.mark.slow
def test_lanelab_train_names_a_missing_clip_file(tiny_store: Path, tmp_path: Path) -> None:
    store, missing = store_without(tiny_store, "clip01", tmp_path)  # a train clip
    result = run(train_command(store, tmp_path / "run"))
    assert result.returncode == 1
    assert result.stderr.strip().splitlines() == [  # old code: 78 lines ending in pyarrow's FileNotFoundError
        f"lanelab-train: {missing}: clip file missing (the store's manifest lists clip 'clip01'); re-ingest the "
        f"store (lanelab-ingest or lanelab-openlane with output={store}) to write it again"]  # fmt: skip


def test_lanelab_eval_names_a_missing_clip_file(trained_checkpoint: Path, tiny_store: Path, tmp_path: Path) -> None:
    store, missing = store_without(tiny_store, "clip03", tmp_path)  # the test clip
    options = load_eval_config([f"checkpoint={trained_checkpoint}", f"store={store}", f"out={tmp_path / 'out'}"])
    with pytest.raises(ClipFileError, match=rf"{missing}: clip file missing .*; re-ingest the store"):
        eval_cli.run(options)  # lanelab-eval prints the message alone, status 1
