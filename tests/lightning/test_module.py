"""LaneDetectionModule with SparseLaneSTP from conf/model: a Lightning run of every mode, streaming
against windowed inference, which frames the loss learns from, pictures for the logger."""

from __future__ import annotations

import json
from pathlib import Path

import lightning.pytorch as pl
import numpy as np
import pytest
import torch
from hydra.utils import instantiate
from lightning.pytorch.loggers import CSVLogger
from tiny_setup import TRAINER, build_store, data_module, model_config

from lanelab.lightning import LaneDetectionModule, OpenLaneWriter, PredictionBatch
from lanelab.viz import GT_COLOR
from lanelab.viz.panels import strip_height


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("store"), [5, 4])


def tiny_module(name: str = "sparselanestp") -> LaneDetectionModule:
    torch.manual_seed(0)
    return instantiate(model_config(name))


@pytest.mark.parametrize(
    "name, sampler, num_frames",
    [("sparselanestp", "window", 3), ("sparselanestp", "stream", 1), ("latr_baseline", "window", 1)],
    ids=["windowed", "streaming", "baseline"],
)
def test_fit_validate_test_and_predict_run(store, tmp_path, name, sampler, num_frames):
    module = tiny_module(name)
    before = [p.detach().clone() for p in module.net.parameters()]
    dm = data_module(store, sampler, num_frames=num_frames, batch_size=2)
    trainer = pl.Trainer(fast_dev_run=True, callbacks=[OpenLaneWriter(tmp_path, ground_truth=store)], **TRAINER)
    trainer.fit(module, dm)
    assert any(not torch.equal(a, b) for a, b in zip(before, module.net.parameters())), "no optimiser step"
    assert torch.isfinite(trainer.callback_metrics["train/loss"])
    for results in (trainer.validate(module, dm, verbose=False), trainer.test(module, dm, verbose=False)):
        assert 0.0 <= next(value for key, value in results[0].items() if key.endswith("/f1")) <= 1.0

    (batch,) = trainer.predict(module, dm)
    assert isinstance(batch, PredictionBatch) and batch.file_paths
    # Every lane slot (tiny: N = 4) at every sample of data.y_grid (20 in the tests).
    assert batch.predictions.points.shape == (len(batch.file_paths), 4, 20, 3)
    for file_path in batch.file_paths:
        json_path = Path(file_path).with_suffix(".json")
        written = json.loads((tmp_path / "predictions" / json_path).read_text())
        assert written["file_path"] == file_path and isinstance(written["lane_lines"], list)
        assert (tmp_path / "ground_truth" / json_path).is_file()
    assert (tmp_path / "test_list.txt").read_text().split() == batch.file_paths


def test_streaming_inference_equals_windowed_inference(store):
    """Streaming over whole clips (stream sampler, one frame a step, memory carried) gives every
    frame the prediction of a window reaching back to its clip's start (window sampler)."""
    module = tiny_module().eval()
    trainer = pl.Trainer(logger=False, **TRAINER)
    streamed = trainer.predict(module, data_module(store, "stream", num_frames=1, batch_size=2))
    windowed = trainer.predict(module, data_module(store, "window", num_frames=5, batch_size=3))

    def by_frame(batches: list[PredictionBatch]) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        lanes = {}
        for batch in batches:
            for i, path in enumerate(batch.file_paths):
                lanes[path] = (batch.predictions.points[i], batch.predictions.score[i])
        return lanes

    streamed, windowed = by_frame(streamed), by_frame(windowed)
    assert len(streamed) == 9 and streamed.keys() == windowed.keys()
    for path in streamed:
        torch.testing.assert_close(streamed[path], windowed[path], rtol=1e-4, atol=1e-4)


def test_streaming_carries_the_memory_and_resets_it_at_clip_starts(store):
    module = tiny_module().eval()
    batch = next(iter(data_module(store, "stream", num_frames=1, batch_size=2).val_dataloader()))
    with torch.no_grad():
        assert not module({**batch, "reset": torch.tensor([True, True])})["memory"].valid.any()  # nothing seen yet
        carried = module({**batch, "reset": torch.tensor([False, False])})["memory"]
        partly = module({**batch, "reset": torch.tensor([True, False])})["memory"]
    assert torch.equal(carried.valid, carried.age == 1)  # one frame seen so far
    assert not partly.valid[0].any() and torch.equal(partly.valid[1], partly.age[1] <= 2)


@pytest.mark.filterwarnings("ignore:You are trying to `self.log\\(\\)`")  # no Trainer here
def test_the_loss_skips_padding_and_unlabeled_frames(store):
    module = tiny_module().eval()  # eval: batch norm must not mix the samples of a batch
    batch = next(iter(data_module(store, "window", num_frames=3, batch_size=2).train_dataloader()))
    first = {key: value[:1] for key, value in batch.items()}
    padded = {**batch, "padding": torch.tensor([False, True])}
    unlabeled = {**batch, "labeled": torch.cat([batch["labeled"][:, :-1], torch.tensor([[True], [False]])], 1)}
    expected = module.training_step(first, 0)
    # The batch size changes the order of float sums (batched matmuls), not the loss.
    torch.testing.assert_close(module.training_step(padded, 0), expected, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(module.training_step(unlabeled, 0), expected, rtol=1e-5, atol=1e-5)

    nothing = module.training_step({**batch, "padding": torch.tensor([True, True])}, 0)
    assert nothing.item() == 0.0 and nothing.requires_grad  # still a step every DDP rank takes


class ImageLogger(CSVLogger):
    """A logger with W&B's image API."""

    def __init__(self, save_dir: Path) -> None:
        super().__init__(save_dir)
        self.images: dict[str, list] = {}

    def log_image(self, key: str, images: list, step: int | None = None) -> None:
        self.images[key] = images


def test_validation_gives_pictures_to_a_logger_that_takes_images(store, tmp_path):
    logger, module = ImageLogger(tmp_path), tiny_module()
    pl.Trainer(logger=logger, **TRAINER).validate(module, data_module(store, "window", num_frames=2, batch_size=3))
    pictures = logger.images["val/pictures"]
    assert len(pictures) == 2 and pictures[0].dtype == np.uint8
    height = module.pictures["height"]
    assert pictures[0].shape[0] > height + 2 * strip_height(height)  # title, captions, panels, legend
    assert np.all(pictures[0] == GT_COLOR[::-1], axis=-1).any()  # the ground truth, RGB
    assert not list(tmp_path.rglob("*.png"))  # given to the logger, not written
