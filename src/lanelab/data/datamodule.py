"""The LightningDataModule: clip store + dataset + temporal samplers + collate, from config.

Hydra builds it from ``conf/data/clips.yaml`` with the sampler group's factories
(``conf/sampler/window.yaml`` or ``stream.yaml``): ``instantiate(cfg.data)``, the data node
referring to ``${sampler.train}`` and ``${sampler.eval}``. A factory is called as
``factory(index, batch_size=..., num_frames=..., rank=..., world_size=...)`` and returns a
sampler of :mod:`lanelab.data.samplers`, whose keys the loader batches ``batch_size`` at a time.
The training loader uses ``train_sampler`` and the photometric augmentation; validation, test
and prediction use ``eval_sampler`` and none. Batches are laid out as :mod:`lanelab.data.dataset`
and :mod:`lanelab.data.collate` describe.

The samplers shard the data over ranks themselves (rank and world size from the trainer), so
the Trainer must run with ``use_distributed_sampler=False``.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Callable, Mapping, Sequence

import lightning.pytorch as pl
import numpy as np
from torch.utils.data import DataLoader, Sampler

from lanelab.data.augment import PhotometricAugment
from lanelab.data.lateral_shift import LateralShift
from lanelab.data.collate import collate_samples
from lanelab.data.dataset import ClipDataset
from lanelab.data.frame_index import SampleKey
from lanelab.data.targets import LaneTargets
from lanelab.data.transforms import ResizeCrop
from lanelab.store import DataError

SamplerFactory = Callable[..., Sampler[SampleKey]]


class ClipDataModule(pl.LightningDataModule):
    """Data loaders over the splits of a clip store.

    store: the store directory. splits: which store split each stage reads ("train", "val",
    "test", "predict" -> "train" | "val" | "test"; a missing or null stage has no loader).
    image_size: (H, W) of the model input; crop: (top, left, height, width) source pixels cut
    out before resizing, or None. num_frames: F per sample. y_grid: {start, stop, num} of the
    resampled lanes. max_lanes: lanes per sample after padding. mean / std: image
    normalisation. augment: training-only photometric augmentation, or None. lateral_shift:
    training-only lateral shift of the ego (lanelab.data.lateral_shift), or None. batch_size:
    samples (streams) per rank and step. Defaults live in conf/data/clips.yaml.
    """

    def __init__(
        self,
        store: str | Path,
        *,
        splits: Mapping[str, str | None],
        image_size: Sequence[int],
        crop: Sequence[int] | None,
        num_frames: int,
        y_grid: Mapping[str, float],
        max_lanes: int,
        mean: Sequence[float],
        std: Sequence[float],
        augment: PhotometricAugment | None,
        lateral_shift: LateralShift | None,
        train_sampler: SamplerFactory,
        eval_sampler: SamplerFactory,
        batch_size: int,
        num_workers: int,
        pin_memory: bool,
    ) -> None:
        super().__init__()
        self.store = Path(store)
        self.splits = dict(splits)
        self.resize = ResizeCrop(int(image_size[0]), int(image_size[1]), None if crop is None else tuple(crop))
        self.num_frames = num_frames
        self.targets = LaneTargets(np.linspace(y_grid["start"], y_grid["stop"], int(y_grid["num"])))
        self.max_lanes = max_lanes
        self.mean, self.std = tuple(mean), tuple(std)
        self.augment, self.lateral_shift = augment, lateral_shift
        self.train_sampler = train_sampler
        self.eval_sampler = eval_sampler
        self.batch_size = batch_size
        self.num_workers = num_workers
        self.pin_memory = pin_memory
        self._datasets: dict[str, ClipDataset] = {}

    def dataset(self, stage: str) -> ClipDataset:
        """The dataset of a stage ("train", "val", "test", "predict"), built once."""
        if stage not in self._datasets:
            self._datasets[stage] = ClipDataset(
                self.store, self.splits[stage], num_frames=self.num_frames, resize=self.resize,
                targets=self.targets, mean=self.mean, std=self.std,
                augment=self.augment if stage == "train" else None,
                lateral_shift=self.lateral_shift if stage == "train" else None,
            )
        return self._datasets[stage]

    def check(self, stages: Sequence[str]) -> None:
        """Read what the stages ("train", "val", "test", "predict") need of the store and draw
        their samplers once, before a model is built: :class:`~lanelab.store.ManifestError` for a
        missing or unreadable store, :class:`~lanelab.store.DataError` naming the stage's
        split for one without clips or windows its sampler cannot draw. A stage without a split
        (``splits.<stage>: null``) needs nothing."""
        for stage in stages:
            if self.splits.get(stage) is not None:
                self._sampler(stage)

    def _sampler(self, stage: str) -> Sampler[SampleKey]:
        dataset = self.dataset(stage)
        factory = self.train_sampler if stage == "train" else self.eval_sampler
        rank, world_size = (None, None) if self.trainer is None else (self.trainer.global_rank, self.trainer.world_size)
        try:
            return factory(dataset.index, batch_size=self.batch_size, num_frames=self.num_frames, rank=rank,
                           world_size=world_size)  # fmt: skip
        except ValueError as err:  # the samplers' own checks of batch_size, num_frames and their windows
            raise DataError(f"{self.store}: cannot draw the {stage} samples from split {self.splits[stage]!r}: {err}") from None

    def _loader(self, stage: str) -> DataLoader | list:
        if self.splits.get(stage) is None:
            return []  # Lightning skips a stage without loaders
        dataset, sampler = self.dataset(stage), self._sampler(stage)
        return DataLoader(
            dataset,
            sampler=sampler,
            batch_size=self.batch_size,
            collate_fn=partial(collate_samples, max_lanes=self.max_lanes),
            num_workers=self.num_workers,
            # The sampler runs in this process, so set_epoch reaches it with workers kept alive.
            persistent_workers=self.num_workers > 0,
            pin_memory=self.pin_memory,
        )

    def train_dataloader(self) -> DataLoader | list:
        return self._loader("train")

    def val_dataloader(self) -> DataLoader | list:
        return self._loader("val")

    def test_dataloader(self) -> DataLoader | list:
        return self._loader("test")

    def predict_dataloader(self) -> DataLoader | list:
        return self._loader("predict")
