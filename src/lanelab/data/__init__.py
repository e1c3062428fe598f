"""Clip datasets: the clip store (format, writing, reading) and what feeds models from it."""

# What feeds models (the LightningDataModule is lanelab.data.datamodule.ClipDataModule, left out
# here so that importing the clip store does not import Lightning).
from lanelab.data.augment import PhotometricAugment
from lanelab.data.collate import collate_samples
from lanelab.data.dataset import ClipDataset
from lanelab.data.frame_index import FrameIndex, SampleKey
from lanelab.data.samplers import StreamSampler, WindowSampler
from lanelab.data.targets import LaneTargets
from lanelab.data.transforms import ResizeCrop
