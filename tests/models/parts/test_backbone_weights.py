"""Pretrained backbones: a ResNet state dict in torchvision's key layout loads into ours."""

from __future__ import annotations

import sys
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from hydra.errors import ConfigCompositionException
from hydra.utils import instantiate

from lanelab.config_checks import ConfigError
from lanelab.experiment.config import load_train_config
from lanelab.models.parts.backbone import ResNet, load_torchvision_weights

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "lightning"))
from tiny_setup import TRAINER, build_store, data_module, model_config  # noqa: E402


def torchvision_layout(resnet: ResNet) -> dict[str, torch.Tensor]:
    """Our ResNet's tensors under torchvision's names (written independently of the loader's
    mapping: walking our modules), plus torchvision's classifier, which the loader ignores."""
    state = {}
    for name, tensor in resnet.state_dict().items():
        parts = name.split(".")
        if parts[0] == "stem":
            state[("conv1." if parts[2] == "0" else "bn1.") + ".".join(parts[3:])] = tensor
            continue
        stage, block, module, inner, rest = int(parts[1]), parts[2], parts[3], parts[4], parts[5:]
        if module == "shortcut":
            target = f"downsample.{inner}"
        else:
            target = ("conv" if inner == "0" else "bn") + module[-1]
        state[".".join([f"layer{stage + 1}", block, target, *rest])] = tensor
    state["fc.weight"], state["fc.bias"] = torch.randn(1000, resnet.out_channels[-1]), torch.randn(1000)
    return state


def test_torchvision_weights_load_into_every_parameter_and_buffer(tmp_path: Path):
    torch.manual_seed(0)
    source = ResNet(18, 16, (1, 2, 3))
    for module in source.modules():  # non-trivial batch-norm statistics as well
        if isinstance(module, torch.nn.BatchNorm2d):
            module.running_mean.normal_()
            module.running_var.uniform_(0.5, 2.0)
    path = tmp_path / "resnet18.pth"
    torch.save(torchvision_layout(source), path)

    target = ResNet(18, 16, (1, 2, 3))
    load_torchvision_weights(target, path)
    for (name, expected), actual in zip(source.state_dict().items(), target.state_dict().values()):
        torch.testing.assert_close(actual, expected, msg=name)
    images = torch.randn(2, 3, 64, 96)
    source.eval(), target.eval()
    for a, b in zip(source(images), target(images)):
        torch.testing.assert_close(a, b)

    torch.save({"model": torchvision_layout(source), "epoch": 90}, path)  # a training checkpoint
    wrapped = ResNet(18, 16, (1, 2, 3))
    load_torchvision_weights(wrapped, path)
    torch.testing.assert_close(wrapped.state_dict(), source.state_dict())


def test_a_file_of_another_depth_or_none_at_all_is_refused_by_name(tmp_path: Path):
    path = tmp_path / "resnet34.pth"
    torch.save(torchvision_layout(ResNet(34, 16, (3,))), path)
    with pytest.raises(ValueError, match="resnet34.pth.*ResNet-18.*unexpected: layer1.2"):
        load_torchvision_weights(ResNet(18, 16, (3,)), path)
    with pytest.raises(ValueError, match="wrong shape"):
        load_torchvision_weights(ResNet(34, 8, (3,)), path)
    with pytest.raises(FileNotFoundError, match="nothing.pth"):
        load_torchvision_weights(ResNet(18, 16, (3,)), tmp_path / "nothing.pth")
    (tmp_path / "garbage.pth").write_bytes(b"not a state dict")
    with pytest.raises(ValueError, match="garbage.pth"):
        load_torchvision_weights(ResNet(18, 16, (3,)), tmp_path / "garbage.pth")


def test_train_config_takes_model_backbone_weights_and_no_other_key(tmp_path: Path):
    base = [f"paths.output_dir={tmp_path}", f"model.backbone.weights={tmp_path / 'resnet50.pth'}"]
    assert load_train_config(base).model.backbone.weights == str(tmp_path / "resnet50.pth")
    with pytest.raises(ConfigCompositionException, match="model.backbone.nope"):
        load_train_config([*base, "model.backbone.nope=1"])
    with pytest.raises(ConfigError, match=r"model\.backbone=.*'nope': 1.*expected \{weights: str \| None\}"):
        load_train_config([*base, "+model.backbone.nope=1"])
    with pytest.raises(ConfigError, match=r"model\.backbone\.weights=3: wrong type"):
        load_train_config([f"paths.output_dir={tmp_path}", "model.backbone.weights=3"])


class StemAtTrainStart(pl.Callback):
    """Keeps the backbone's first convolution as it is when the training steps start."""

    def on_train_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self.weight = pl_module.net.backbone.stem[0][0].weight.detach().clone()


def test_model_backbone_weights_starts_training_unless_a_checkpoint_resumes(tmp_path: Path):
    """model.backbone.weights=PATH: the weights are in the backbone when training starts; a
    resumed run starts from its checkpoint's weights instead."""
    reference = instantiate(model_config("sparselanestp"), _convert_="all").net.backbone
    torch.nn.init.normal_(reference.stem[0][0].weight)
    path = tmp_path / "weights.pth"
    torch.save(torchvision_layout(reference), path)
    module = instantiate(model_config("sparselanestp", f"model.backbone.weights={path}"), _convert_="all")
    assert not torch.equal(module.net.backbone.stem[0][0].weight, reference.stem[0][0].weight)

    store = build_store(tmp_path / "store", [3])
    settings = {**TRAINER, "logger": False, "enable_checkpointing": False, "limit_val_batches": 0}
    spy = StemAtTrainStart()
    trainer = pl.Trainer(**settings, max_steps=1, callbacks=[spy])
    trainer.fit(module, datamodule=data_module(store, "stream", num_frames=1, batch_size=1))
    torch.testing.assert_close(spy.weight, reference.stem[0][0].weight)

    checkpoint = tmp_path / "run.ckpt"
    trainer.save_checkpoint(checkpoint)
    other = tmp_path / "other.pth"
    torch.nn.init.normal_(reference.stem[0][0].weight)
    torch.save(torchvision_layout(reference), other)
    resumed = instantiate(model_config("sparselanestp", f"model.backbone.weights={other}"), _convert_="all")
    spy = StemAtTrainStart()
    trainer = pl.Trainer(**settings, max_steps=2, callbacks=[spy])
    trainer.fit(resumed, datamodule=data_module(store, "stream", num_frames=1, batch_size=1), ckpt_path=checkpoint)
    saved = torch.load(checkpoint, map_location="cpu", weights_only=False)["state_dict"]
    torch.testing.assert_close(spy.weight, saved["net.backbone.stem.0.0.weight"])
