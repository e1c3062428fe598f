"""ClipDataModule from the Hydra config files: batch layout, workers, and a Lightning run."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from hydra.utils import instantiate
from omegaconf import OmegaConf
from synthetic_clips import HEIGHT, WIDTH, build_store

from lanelab.data.datamodule import ClipDataModule
from lanelab.store import DataError

CONF = Path(__file__).resolve().parents[2] / "conf"
CLIPS = {"train": [7, 5, 9], "val": [6, 4]}


def data_module(store: Path, sampler: str, **overrides) -> ClipDataModule:
    """The DataModule exactly as conf/data/clips.yaml + conf/sampler/<sampler>.yaml make it."""
    cfg = OmegaConf.create({
        "data": OmegaConf.load(CONF / "data" / "clips.yaml"),
        "sampler": OmegaConf.load(CONF / "sampler" / f"{sampler}.yaml"),
    })
    settings = {"store": str(store), "image_size": [32, 40], "batch_size": 3, "num_workers": 0, **overrides}
    cfg.data = OmegaConf.merge(cfg.data, settings)
    return instantiate(cfg.data)


def check_batch(batch: dict, batch_size: int, num_frames: int, dm: ClipDataModule) -> None:
    B, F, S, L = batch_size, num_frames, len(dm.targets.y), dm.max_lanes
    expected = {
        "images": ((B, F, 3, 32, 40), torch.float32),
        "K": ((B, F, 3, 3), torch.float32),
        "T_lane_cam": ((B, F, 4, 4), torch.float32),
        "T_world_lane": ((B, F, 4, 4), torch.float64),
        "valid": ((B, F), torch.bool),
        "labeled": ((B, F), torch.bool),
        "timestamp_ns": ((B, F), torch.int64),
        "frame_index": ((B, F), torch.int64),
        "reset": ((B,), torch.bool),
        "padding": ((B,), torch.bool),
        "gt_y": ((B, S), torch.float32),
        "gt_x": ((B, L, S), torch.float32),
        "gt_z": ((B, L, S), torch.float32),
        "gt_vis": ((B, L, S), torch.float32),
        "gt_category": ((B, L), torch.int64),
        "gt_track_id": ((B, L), torch.int64),
        "gt_mask": ((B, L), torch.bool),
    }
    for key, (shape, dtype) in expected.items():
        assert (tuple(batch[key].shape), batch[key].dtype) == (shape, dtype), key
    assert set(batch) == set(expected) | {"clip_id", "tags"}
    assert len(batch["clip_id"]) == len(batch["tags"]) == B
    K = batch["K"][0, -1]  # intrinsics scaled from the 64 x 48 store images to 40 x 32
    assert K[0, 0] == pytest.approx(60.0 * 40 / WIDTH) and K[1, 1] == pytest.approx(60.0 * 32 / HEIGHT)


@pytest.mark.parametrize("sampler, num_frames", [("window", 4), ("stream", 1)])
def test_train_and_val_batches_have_the_documented_layout(tmp_path, sampler, num_frames):
    dm = data_module(build_store(tmp_path, CLIPS), sampler, num_frames=num_frames)
    for loader in (dm.train_dataloader(), dm.val_dataloader()):
        batches = list(loader)
        assert len(batches) == len(loader.batch_sampler)
        for batch in batches:
            check_batch(batch, 3, num_frames, dm)
    val_frames = sum(int((~b["padding"]).sum()) for b in batches)
    labeled_val_frames = 6 + 4 if sampler == "window" else 10  # every val frame labeled; stream: all frames
    assert val_frames == labeled_val_frames
    if sampler == "stream":
        assert batches[0]["reset"].all()


def test_two_workers_give_the_same_batches(tmp_path):
    store = build_store(tmp_path, CLIPS, label_every=2)
    batches = [list(data_module(store, "window", num_workers=workers).val_dataloader()) for workers in (0, 2)]
    assert len(batches[0]) == len(batches[1]) > 1
    for a, b in zip(*batches):
        assert a["clip_id"] == b["clip_id"]
        torch.testing.assert_close(a["images"], b["images"])
        torch.testing.assert_close(a["frame_index"], b["frame_index"])


def test_a_stage_without_split_has_no_loader(tmp_path):
    dm = data_module(build_store(tmp_path, CLIPS), "window", splits={"val": None})
    assert dm.val_dataloader() == []
    with pytest.raises(DataError, match="split 'test' has no clips"):
        dm.test_dataloader()


class FrameRecorder(pl.LightningModule):
    """Trains nothing; records the frames each step sees."""

    def __init__(self) -> None:
        super().__init__()
        self.weight = torch.nn.Parameter(torch.zeros(()))
        self.seen: dict[str, list] = {"train": [], "predict": []}

    def training_step(self, batch, batch_idx):
        self.seen["train"].append((self.current_epoch, batch["frame_index"][:, -1].tolist(), batch["clip_id"]))
        return (self.weight - batch["images"].mean()) ** 2

    def predict_step(self, batch, batch_idx):
        self.seen["predict"].append(batch["padding"])
        return batch["frame_index"][:, -1]

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.1)


def test_lightning_fit_and_predict_with_streams(tmp_path):
    dm = data_module(build_store(tmp_path, {"train": [7, 5, 9, 4, 6], "test": [6, 4]}), "stream", num_frames=1,
                     splits={"train": "train", "val": None, "predict": "test"}, augment=None)
    model = FrameRecorder()
    trainer = pl.Trainer(accelerator="cpu", devices=1, max_epochs=2, use_distributed_sampler=False, logger=False,
                         enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.fit(model, datamodule=dm)
    steps = [(epoch, tuple(f), tuple(c)) for epoch, f, c in model.seen["train"]]
    per_epoch = [[s for s in steps if s[0] == e] for e in (0, 1)]
    assert len(per_epoch[0]) == len(per_epoch[1]) == 11  # 31 frames over 3 streams
    assert trainer.train_dataloader.sampler.epoch == 1  # Lightning's set_epoch reached the sampler
    assert [s[1:] for s in per_epoch[0]] != [s[1:] for s in per_epoch[1]]

    predictions = trainer.predict(model, datamodule=dm)
    padding = torch.cat(model.seen["predict"])
    assert int((~padding).sum()) == 10 and len(predictions) == 6  # whole clips: longest stream of 6


class StepCounter(pl.LightningModule):
    """Writes the (step, frames) each rank trains on; an all-reduce per step would hang on unequal steps."""

    def __init__(self, out_dir: Path) -> None:
        super().__init__()
        self.weight = torch.nn.Parameter(torch.zeros(()))
        self.out_dir = out_dir
        self.seen: list = []

    def training_step(self, batch, batch_idx):
        total = torch.tensor(float(len(batch["padding"])))
        torch.distributed.all_reduce(total)
        current = batch["frame_index"][:, -1].tolist()
        frames = [(c, f) for c, f, p in zip(batch["clip_id"], current, batch["padding"]) if not p]
        self.seen.append((self.current_epoch, frames, float(total)))
        return (self.weight - batch["images"].mean()) ** 2

    def on_train_end(self) -> None:
        (self.out_dir / f"rank{self.global_rank}.json").write_text(json.dumps(self.seen))

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.1)


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_two_rank_ddp_streams_see_every_frame_once_per_epoch_with_equal_steps(tmp_path):
    """Ranks and world size reach the sampler from the trainer (ddp_spawn, gloo)."""
    clips = {"train": [7, 5, 9, 4, 6]}  # 31 frames: uneven over 2 ranks x 3 streams
    dm = data_module(build_store(tmp_path / "store", clips), "stream", num_frames=2, augment=None,
                     splits={"train": "train"}, num_workers=0)
    trainer = pl.Trainer(accelerator="cpu", devices=2, strategy="ddp_spawn", max_epochs=2,
                         use_distributed_sampler=False, logger=False, enable_checkpointing=False,
                         enable_progress_bar=False, enable_model_summary=False)
    trainer.fit(StepCounter(tmp_path), datamodule=dm)

    ranks = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in range(2)]
    assert len(ranks[0]) == len(ranks[1]) == 2 * 6  # ceil(31 / (2 * 3)) steps per epoch
    assert all(total == 6 for steps in ranks for _, _, total in steps)
    for epoch in range(2):
        frames = Counter(tuple(f) for steps in ranks for e, fs, _ in steps if e == epoch for f in fs)
        assert frames == Counter((f"clip{c:02d}", p) for c, n in enumerate(clips["train"]) for p in range(n))
