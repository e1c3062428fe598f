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
def checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """last.ckpt of the tiny SparseLaneSTP (T = 3 memory frames) after a few streaming steps: its
    run config evaluates by streaming whole clips, as lanelab-predict runs logs."""
    threads = torch.get_num_threads()
    store = build_store(tmp_path_factory.mktemp("tiny_store"))
    run = tmp_path_factory.mktemp("tiny_run")
    # A model this young sees every point at visibility ~0.45: the threshold lets its lanes show.
    overrides = ["sampler=stream", "data.num_frames=1", "trainer.max_epochs=10", f"trainer.max_steps={TRAIN_STEPS}",
                 "model.metric.visibility_threshold=0.4"]
    train(load_train_config(tiny_overrides(store, run, *overrides)))
    torch.set_num_threads(threads)  # the tiny experiment sets one thread for its process
    return run / "checkpoints" / "last.ckpt"


@pytest.fixture(autouse=True)
def restore_torch_threads() -> Iterator[None]:
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
