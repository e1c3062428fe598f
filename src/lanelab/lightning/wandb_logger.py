"""Lightning's WandbLogger without the ``anonymous`` argument it always hands ``wandb.init``:
wandb deprecated the setting and warns on every run where it is given at all, even as None."""

from __future__ import annotations

from typing import Any

from lightning.pytorch.loggers import WandbLogger as LightningWandbLogger


class WandbLogger(LightningWandbLogger):
    """Lightning's, same arguments (``anonymous`` left out)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._wandb_init.pop("anonymous", None)
