"""A lanelab-train checkpoint as a detector to run on frames, without a store or a Trainer.

lanelab-train writes the run's resolved config into every checkpoint
(:mod:`lanelab.experiment.build`), so :func:`load_trained` rebuilds from the file alone what
predicting needs: the LaneDetectionModule with its weights (the detector, its visibility
threshold and NMS), the image pipeline it was trained with (resize / crop, normalisation;
:mod:`lanelab.data.transforms`) and the y grid its lanes are sampled at (``data.y_grid``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from hydra.utils import instantiate
from torch import Tensor

from lanelab.config_checks import ConfigError
from lanelab.data.transforms import Normalise, ResizeCrop
from lanelab.deploy.devices import device_for
from lanelab.experiment.build import CONFIG_KEY, read_checkpoint
from lanelab.finite import NonFiniteError
from lanelab.lightning.checkpoint import describe, non_finite_tensors
from lanelab.lightning.module import LaneDetectionModule
from lanelab.models.api import LaneDetector
from lanelab.store import FrameRecord
from lanelab.store.image_codec import decode_image

@dataclass
class TrainedDetector:
    """A checkpoint's model in eval mode on ``device``, with its input pipeline (``resize``,
    ``normalise``) and the y grid (S,) of its lanes, metres. ``config``: the run config."""

    checkpoint: Path
    module: LaneDetectionModule
    resize: ResizeCrop
    normalise: Normalise
    y: Tensor
    device: torch.device
    config: dict[str, Any]

    @property
    def net(self) -> LaneDetector:
        return self.module.net

    def model_input(self, record: FrameRecord) -> dict[str, Tensor]:
        """One frame as a detector's ``step`` takes it (B = 1): images (1, 3, H, W) float32,
        K (1, 3, 3) and T_lane_cam (1, 4, 4) float32, T_world_lane (1, 4, 4) float64; the
        image decoded, resized and normalised as the training data was (lanelab.data.dataset)."""
        image, K = self.resize(decode_image(record), record.K)
        tensors = {
            "images": self.normalise(image[None]),
            "K": torch.from_numpy(np.asarray(K)).float()[None],
            "T_lane_cam": torch.from_numpy(np.asarray(record.T_lane_cam)).float()[None],
            "T_world_lane": torch.from_numpy(np.asarray(record.T_world_lane)).double()[None],
        }
        return {key: value.to(self.device) for key, value in tensors.items()}


def load_trained(checkpoint: str | Path, accelerator: str = "cpu") -> TrainedDetector:
    """Rebuild a lanelab-train checkpoint's model and input pipeline on one device; on the CPU,
    torch runs the run config's ``cpu_threads`` (when set), as the run did.

    Raises ConfigError naming the checkpoint when it cannot be read, holds no run config or
    its weights do not fit the model of its config; NonFiniteError when its weights hold NaN
    or inf.
    """
    device = device_for(accelerator)
    content = read_checkpoint(checkpoint)
    config, state = content[CONFIG_KEY], content.get("state_dict")
    if not isinstance(state, dict):
        raise ConfigError(f"checkpoint={checkpoint}: holds no state_dict (weights)")
    names = non_finite_tensors(state)
    if names:
        raise NonFiniteError(f"{checkpoint}: the checkpoint's weights hold NaN or inf in {describe(names)}")
    module = instantiate(config["model"])
    try:
        module.load_state_dict(state)
    except RuntimeError as err:
        first = str(err).strip().splitlines()[:2]
        raise ConfigError(f"checkpoint={checkpoint}: its weights do not fit the model of its config: "
                          f"{' '.join(line.strip() for line in first)}") from None
    module.eval().to(device)
    if device.type == "cpu" and config.get("cpu_threads") is not None:
        torch.set_num_threads(config["cpu_threads"])  # as the run did: extra threads slow a shared CPU
    data = config["data"]
    height, width = data["image_size"]
    crop = data.get("crop")
    grid = data["y_grid"]
    return TrainedDetector(
        checkpoint=Path(checkpoint),
        module=module,
        resize=ResizeCrop(int(height), int(width), None if crop is None else tuple(int(c) for c in crop)),
        normalise=Normalise(data["mean"], data["std"]),
        y=torch.linspace(grid["start"], grid["stop"], int(grid["num"]), device=device),
        device=device,
        config=config,
    )
