"""NaN or inf never passes silently: a store's frame names its clip and frame, a loss names its
step and batch and takes no optimiser step, no checkpoint of NaN weights is written or evaluated,
and last.ckpt is overwritten in place."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tiny_store import build_store, tiny_overrides

from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train
from lanelab.finite import NonFiniteError
from lanelab.models.sparselanestp import SparseLaneSTPCriterion
from lanelab.store import ClipStore, write_clip

LEGACY = Path(__file__).parent / "data" / "legacy_sparselanestp.ckpt"
STREAM = ["sampler=stream", "data.num_frames=1", "trainer.limit_val_batches=1"]


def finite_weights(checkpoint: Path) -> bool:
    state = torch.load(checkpoint, map_location="cpu", weights_only=False)["state_dict"]
    return all(torch.isfinite(value).all() for value in state.values() if value.is_floating_point())


@pytest.mark.parametrize("field", ["K", "T_world_lane", "lanes[1].points"])
def test_nan_in_the_store_names_the_clip_and_frame(field: str, tmp_path: Path) -> None:
    store = build_store(tmp_path / "store")
    frames = ClipStore(store).read_frames("clip01")
    frame = frames[2]
    {"K": frame.K, "T_world_lane": frame.T_world_lane, "lanes[1].points": frame.lanes[1].points}[field][0, 0] = math.nan
    write_clip(store, "clip01", frames)  # as older code or a hand-made store could have written it
    with pytest.raises(NonFiniteError, match=rf"clip clip01, frame timestamp_ns=200000000: NaN or inf in {re.escape(field)}"):
        train(load_train_config(tiny_overrides(store, tmp_path / "run", *STREAM, "trainer.max_steps=6")))


def test_a_non_finite_loss_names_the_batch_and_no_checkpoint_is_versioned(
    tiny_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    train(load_train_config(tiny_overrides(tiny_store, tmp_path, *STREAM, "trainer.max_steps=2")))
    criterion, calls = SparseLaneSTPCriterion.forward, []

    def nan_at_the_third_step(self, outputs, batch):
        losses = criterion(self, outputs, batch)
        calls.append(1)
        return {**losses, "total": losses["total"] * math.nan} if len(calls) == 3 else losses

    monkeypatch.setattr(SparseLaneSTPCriterion, "forward", nan_at_the_third_step)
    # A second run into the same folder: its crash-time checkpoint replaces last.ckpt.
    with pytest.raises(NonFiniteError) as error:
        train(load_train_config(tiny_overrides(tiny_store, tmp_path, *STREAM, "trainer.max_steps=6")))
    message = str(error.value)
    assert message.startswith("step 2: the loss is not finite (total=nan) on the batch of frames (clip_id@timestamp_ns) ")
    assert "clip00@200000000" in message and "clip01@200000000" in message
    checkpoints = sorted(path.name for path in (tmp_path / "checkpoints").iterdir())
    assert checkpoints == ["last.ckpt"]  # never last-v1.ckpt, nor an epoch/step file of the crash (issue 37, case 7)
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert torch.load(last, weights_only=False)["global_step"] == 2 and finite_weights(last)


@pytest.mark.slow
def test_a_checkpoint_of_nan_weights_is_not_evaluated(tiny_store: Path, tmp_path: Path) -> None:
    content = torch.load(LEGACY, map_location="cpu", weights_only=False)
    name = next(key for key, value in content["state_dict"].items() if value.is_floating_point())
    content["state_dict"][name].view(-1)[0] = math.nan
    spoiled = tmp_path / "nan.ckpt"
    torch.save(content, spoiled)
    result = subprocess.run([sys.executable, "-m", "lanelab.experiment.eval_cli", f"checkpoint={spoiled}",
                             f"store={tiny_store}", f"out={tmp_path / 'out'}", "blind_prior=false"],
                            capture_output=True, text=True, timeout=300)  # fmt: skip
    assert result.returncode == 1
    assert result.stderr.strip().splitlines()[-1] == (
        f"lanelab-eval: {spoiled}: the checkpoint's weights hold NaN or inf in 1 tensors ({name})")
    assert not list((tmp_path / "out").rglob("*.json"))
