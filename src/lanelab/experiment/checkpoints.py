"""Checkpoint files a run is given, checked before they are used: each fault is one
:class:`~lanelab.config_checks.ConfigError` naming the option and the file. A file that cannot
be read (missing, empty, truncated, not written by ``torch.save``), one that is no Lightning
checkpoint (a plain state dict), weights of another model than the run builds, a training state
past the run's ``max_epochs``.

Files are mapped, not read (``torch.load(mmap=True)``): a check costs little even for large
checkpoints, which Lightning then loads once more.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import torch

from lanelab.config_checks import ConfigError
from lanelab.lightning.checkpoint import describe

LAST = "last"  # ckpt_path=last: the run folder's last.ckpt (Lightning's name)


def load_checkpoint(path: str | Path, key: str) -> dict[str, Any]:
    """A Lightning checkpoint's content on the CPU, its tensors mapped from the file. Raises
    ConfigError naming ``key=path`` when the file cannot be read or holds no Lightning state."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{key}={path}: no such file")
    if path.stat().st_size == 0:
        raise ConfigError(f"{key}={path}: an empty file, not a checkpoint")
    if not zipfile.is_zipfile(path):  # what torch.save writes; a cut file has lost the archive's end
        raise ConfigError(f"{key}={path}: not a readable checkpoint (truncated, or not written by torch.save)")
    try:
        content = torch.load(path, map_location="cpu", weights_only=False, mmap=True)
    except Exception as err:  # torch raises many kinds for a damaged file
        raise ConfigError(f"{key}={path}: not a readable checkpoint ({str(err).strip().splitlines()[0]})") from None
    if isinstance(content, Mapping) and content and all(isinstance(v, torch.Tensor) for v in content.values()):
        raise ConfigError(f"{key}={path}: a plain state dict ({len(content)} tensors), not a checkpoint of "
                          "lanelab-train (weights with the optimiser, loops and run config)")
    if not isinstance(content, dict) or not isinstance(content.get("state_dict"), Mapping):
        raise ConfigError(f"{key}={path}: not a checkpoint of lanelab-train (no Lightning state_dict)")
    return content


def check_weights_fit(module: torch.nn.Module, state: Mapping[str, Any], key: str, path: str | Path, model: str) -> None:
    """ConfigError naming ``key=path`` when the state dict's tensors are not the module's (names
    and shapes); ``model`` says whose model it is ("this run's", "its run config's")."""
    own = module.state_dict()
    faults = [f"{describe(names)} {what}" for names, what in (
        ([name for name in own if name not in state], "missing"),
        ([name for name in state if name not in own], "not in the model"),
        ([name for name in own if name in state and tuple(own[name].shape) != tuple(state[name].shape)], "of other shapes"),
    ) if names]  # fmt: skip
    if faults:
        net = getattr(module, "net", module)
        raise ConfigError(f"{key}={path}: its weights are not those of {model} model ({type(net).__name__}): "
                          f"{'; '.join(faults)}")


def check_resume(trainer: pl.Trainer, module: pl.LightningModule, ckpt_path: str, fitting: bool) -> None:
    """The ``ckpt_path`` of lanelab-train, before Trainer.fit / test loads it: readable, this
    run's model's weights, and when fitting not past ``max_epochs``. ``last`` is checked when the
    run folder has one (without one, Lightning starts afresh)."""
    path = _last_checkpoint(trainer) if ckpt_path == LAST else Path(ckpt_path)
    if path is None:
        return
    content = load_checkpoint(path, "ckpt_path")
    check_weights_fit(module, content["state_dict"], "ckpt_path", path, "this run's")
    epoch, max_epochs = content.get("epoch"), trainer.max_epochs
    if fitting and isinstance(epoch, int) and max_epochs not in (None, -1) and epoch > max_epochs:
        raise ConfigError(f"ckpt_path={path}: the checkpoint is at epoch {epoch} (step "
                          f"{content.get('global_step')}), past trainer.max_epochs={max_epochs}; give "
                          f"trainer.max_epochs={epoch} or more to train on, or train=false to test or evaluate it")


def _last_checkpoint(trainer: pl.Trainer) -> Path | None:
    """The checkpoint callback's ``last.ckpt``, if there is one."""
    folder = getattr(trainer.checkpoint_callback, "dirpath", None)
    path = None if folder is None else Path(folder) / f"{LAST}.ckpt"
    return path if path is not None and path.is_file() else None
