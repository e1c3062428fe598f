"""The device a trained model runs on outside a Trainer: ``accelerator=cpu|gpu|auto``, one device.

No torch at import: the command-line tools check their options before loading it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from lanelab.config_checks import ConfigError

if TYPE_CHECKING:
    import torch

ACCELERATORS = ("cpu", "gpu", "auto")


def device_for(accelerator: str) -> torch.device:
    """The one device of ``accelerator``: "cpu", "gpu" (CUDA; ConfigError without one) or
    "auto" (CUDA if there is one)."""
    import torch

    if accelerator not in ACCELERATORS:
        raise ConfigError(f"accelerator={accelerator!r} is not one of {', '.join(ACCELERATORS)}")
    if accelerator == "gpu" and not torch.cuda.is_available():
        raise ConfigError("accelerator=gpu: no CUDA device here (accelerator=cpu or auto runs on the CPU)")
    return torch.device("cuda" if accelerator != "cpu" and torch.cuda.is_available() else "cpu")
