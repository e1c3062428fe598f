"""Lightning's WandbLogger without the ``anonymous`` argument it always hands ``wandb.init``
(wandb deprecated the setting and warns on every run where it is given at all, even as None),
and silent offline: wandb's banner and closing summary (some 30 lines) say nothing a lanelab run
does not, and its files are the same (``<save_dir>/wandb/offline-run-*``)."""

from __future__ import annotations

from typing import Any

import wandb
from lightning.pytorch.loggers import WandbLogger as LightningWandbLogger


class WandbLogger(LightningWandbLogger):
    """Lightning's, same arguments (``anonymous`` left out; ``settings`` silent when offline
    unless given)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._wandb_init.pop("anonymous", None)
        if kwargs.get("offline"):
            self._wandb_init.setdefault("settings", wandb.Settings(silent=True))
