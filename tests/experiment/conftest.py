from collections.abc import Iterator
from pathlib import Path

import pytest
import torch
from tiny_store import build_store, tiny_overrides

from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train


@pytest.fixture(scope="session")
def tiny_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("tiny_store"))


@pytest.fixture(autouse=True)
def restore_torch_threads() -> Iterator[None]:
    """The tiny experiment sets cpu_threads=1 for its process; later tests get theirs back."""
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def trained_checkpoint(tiny_store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """last.ckpt of the tiny experiment after 3 epochs of 2 steps: at epoch 2 (Lightning counts from 0), step 6."""
    out = tmp_path_factory.mktemp("trained")
    steps = ["trainer.max_epochs=3", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1"]
    train(load_train_config(tiny_overrides(tiny_store, out, *steps)))
    return out / "checkpoints" / "last.ckpt"
