"""What feeds models from a clip store (:mod:`lanelab.store`): frame indices, samplers, datasets.

The LightningDataModule, :class:`lanelab.data.datamodule.ClipDataModule`, is left out here so
that importing the samplers and datasets does not import Lightning.
"""

from lanelab.data.augment import PhotometricAugment
from lanelab.data.collate import collate_samples
from lanelab.data.dataset import ClipDataset
from lanelab.data.frame_index import FrameIndex, SampleKey
from lanelab.data.samplers import StreamSampler, WindowSampler
from lanelab.data.targets import LaneTargets
from lanelab.data.transforms import ResizeCrop
