import pytest
import torch

from lanelab.models.parts.backbone import ResNet
from lanelab.models.parts.fpn import FPN


@pytest.mark.parametrize(
    ("depth", "base_width", "channels"),
    [
        (18, 64, [64, 128, 256, 512]),
        (34, 64, [64, 128, 256, 512]),
        (50, 64, [256, 512, 1024, 2048]),
        (50, 8, [32, 64, 128, 256]),
    ],
)
def test_resnet_channels_and_strides(depth, base_width, channels):
    backbone = ResNet(depth, base_width, out_stages=(0, 1, 2, 3))
    assert backbone.out_channels == channels
    assert backbone.strides == [4, 8, 16, 32]
    # The paper's ResNet-50 has torchvision's 23.5 M parameters without the classifier.
    if (depth, base_width) == (50, 64):
        assert sum(p.numel() for p in backbone.parameters()) == 23_508_032


@pytest.mark.parametrize("depth", [18, 34, 50])
def test_tiny_resnet_fpn_shapes(depth):
    backbone = ResNet(depth, base_width=8, out_stages=(1, 2, 3))
    neck = FPN(backbone.out_channels, out_channels=16, num_levels=4)
    features = backbone(torch.randn(2, 3, 64, 96))
    assert [f.shape[1] for f in features] == backbone.out_channels
    assert [f.shape[-2:] for f in features] == [(8, 12), (4, 6), (2, 3)]
    pyramid = neck(features)
    # LATR's neck: strides 8, 16, 32 and an extra level at 64.
    assert [tuple(f.shape) for f in pyramid] == [(2, 16, 8, 12), (2, 16, 4, 6), (2, 16, 2, 3), (2, 16, 1, 2)]
    assert [tuple(f.shape) for f in FPN(backbone.out_channels, 16, num_levels=2)(features)] == [(2, 16, 8, 12), (2, 16, 4, 6)]


def test_tiny_resnet_forward_backward():
    backbone = ResNet(18, base_width=8, out_stages=(1, 2, 3))
    neck = FPN(backbone.out_channels, out_channels=16, num_levels=4)
    images = torch.randn(2, 3, 64, 96, requires_grad=True)
    loss = sum(level.square().mean() for level in neck(backbone(images)))
    loss.backward()
    for name, parameter in [*backbone.named_parameters(), *neck.named_parameters()]:
        assert parameter.grad is not None and parameter.grad.abs().sum() > 0, name
    assert images.grad.abs().sum() > 0


def test_unknown_depth_is_rejected():
    with pytest.raises(ValueError, match="depth"):
        ResNet(101, 64, out_stages=(1, 2, 3))
