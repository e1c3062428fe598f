"""What the lanelab-predict and lanelab-export tests run on: a tiny model trained for a few
streaming steps on the experiment tests' tiny store, and small synthetic drive logs written as
the ingest tests write them (their helpers)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import torch

TESTS = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(TESTS / "ingest"), str(TESTS / "experiment")]  # their helpers

from log_fixtures import drive, synth_log  # noqa: E402, F401 (fixtures)
from tiny_store import build_store, tiny_overrides  # noqa: E402

from lanelab.experiment.config import load_train_config  # noqa: E402
from lanelab.experiment.train import train  # noqa: E402

TRAIN_STEPS = 4


@pytest.fixture(scope="session")
def tiny_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("tiny_store"))


def trained_checkpoint(store: Path, run: Path, *overrides: str) -> Path:
    """last.ckpt of the tiny experiment (with these overrides) after a few streaming steps: its
    run config evaluates by streaming whole clips, as lanelab-predict runs logs."""
    threads = torch.get_num_threads()
    # A model this young sees every point at visibility ~0.45: the threshold lets its lanes show.
    steps = ["sampler=stream", "data.num_frames=1", "trainer.max_epochs=10", f"trainer.max_steps={TRAIN_STEPS}",
             "model.metric.visibility_threshold=0.4"]
    train(load_train_config(tiny_overrides(store, run, *steps, *overrides)))
    torch.set_num_threads(threads)  # the tiny experiment sets one thread for its process
    return run / "checkpoints" / "last.ckpt"


@pytest.fixture(scope="session")
def checkpoint(tiny_store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny SparseLaneSTP (T = 3 memory frames), trained a few steps."""
    return trained_checkpoint(tiny_store, tmp_path_factory.mktemp("tiny_run"))


@pytest.fixture(scope="session")
def bi2lane_checkpoint(tiny_store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny Bi²Lane (N = 3 history frames), trained a few steps."""
    return trained_checkpoint(tiny_store, tmp_path_factory.mktemp("tiny_bi2lane_run"), "model=bi2lane")


@pytest.fixture(autouse=True)
def restore_torch_threads() -> Iterator[None]:
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
