"""ResNet-18/34/50 backbone (He et al. 2016) in plain PyTorch, trained from scratch or from
weights in torchvision's key layout (:func:`load_torchvision_weights`).

The widths are a constructor argument so the same code builds the paper's ResNet-50
(base_width=64) and a tiny variant (e.g. base_width=8) that trains on a laptop CPU.
The forward returns the outputs of the four stages C2..C5 (strides 4, 8, 16, 32), or the
subset chosen by ``out_stages``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch
from torch import Tensor, nn

# depth -> (block type, blocks per stage), as in the ResNet paper, Table 1.
_LAYOUTS = {18: ("basic", (2, 2, 2, 2)), 34: ("basic", (3, 4, 6, 3)), 50: ("bottleneck", (3, 4, 6, 3))}
_EXPANSION = {"basic": 1, "bottleneck": 4}
STAGE_STRIDES = (4, 8, 16, 32)


def _conv_bn(in_channels: int, out_channels: int, kernel_size: int, stride: int = 1) -> nn.Sequential:
    conv = nn.Conv2d(in_channels, out_channels, kernel_size, stride, padding=kernel_size // 2, bias=False)
    return nn.Sequential(conv, nn.BatchNorm2d(out_channels))


class BasicBlock(nn.Module):
    """Two 3x3 convolutions with an identity (or 1x1 projection) shortcut."""

    def __init__(self, in_channels: int, width: int, stride: int) -> None:
        super().__init__()
        self.conv1 = _conv_bn(in_channels, width, 3, stride)
        self.conv2 = _conv_bn(width, width, 3)
        self.shortcut = _shortcut(in_channels, width, stride)

    def forward(self, x: Tensor) -> Tensor:
        out = self.conv2(torch.relu(self.conv1(x)))
        return torch.relu(out + self.shortcut(x))


class Bottleneck(nn.Module):
    """1x1 reduce, 3x3 (strided, as torchvision's "ResNet v1.5"), 1x1 expand by 4."""

    def __init__(self, in_channels: int, width: int, stride: int) -> None:
        super().__init__()
        out_channels = width * _EXPANSION["bottleneck"]
        self.conv1 = _conv_bn(in_channels, width, 1)
        self.conv2 = _conv_bn(width, width, 3, stride)
        self.conv3 = _conv_bn(width, out_channels, 1)
        self.shortcut = _shortcut(in_channels, out_channels, stride)

    def forward(self, x: Tensor) -> Tensor:
        out = torch.relu(self.conv2(torch.relu(self.conv1(x))))
        return torch.relu(self.conv3(out) + self.shortcut(x))


def _shortcut(in_channels: int, out_channels: int, stride: int) -> nn.Module:
    if stride == 1 and in_channels == out_channels:
        return nn.Identity()
    return _conv_bn(in_channels, out_channels, 1, stride)


class ResNet(nn.Module):
    """ResNet feature extractor.

    depth: 18, 34 or 50. base_width: channels of the stem and of the first stage (64 in the
    paper; stage k has base_width * 2**k, times 4 at the output of bottleneck stages).
    out_stages: which of the stages 0..3 (C2..C5) to return.
    """

    def __init__(self, depth: int, base_width: int, out_stages: Sequence[int]) -> None:
        super().__init__()
        if depth not in _LAYOUTS:
            raise ValueError(f"ResNet depth must be one of {sorted(_LAYOUTS)}, got {depth}")
        if not out_stages or not set(out_stages) <= {0, 1, 2, 3}:
            raise ValueError(f"out_stages must be a non-empty subset of 0..3, got {out_stages}")
        kind, blocks = _LAYOUTS[depth]
        self.depth, self.base_width = depth, base_width
        block = BasicBlock if kind == "basic" else Bottleneck
        self.out_stages = tuple(sorted(out_stages))

        self.stem = nn.Sequential(
            _conv_bn(3, base_width, 7, stride=2), nn.ReLU(inplace=True), nn.MaxPool2d(3, 2, padding=1)
        )
        stages, channels, in_channels = [], [], base_width
        for index, num_blocks in enumerate(blocks):
            width = base_width * 2**index
            stride = 1 if index == 0 else 2
            layers = []
            for b in range(num_blocks):
                layers.append(block(in_channels, width, stride if b == 0 else 1))
                in_channels = width * _EXPANSION[kind]
            stages.append(nn.Sequential(*layers))
            channels.append(in_channels)
        self.stages = nn.ModuleList(stages)
        self.out_channels = [channels[i] for i in self.out_stages]
        self.strides = [STAGE_STRIDES[i] for i in self.out_stages]
        self._init_weights()

    def _init_weights(self) -> None:
        # From scratch (no pretrained weights here): He init, as torchvision's ResNet.
        for module in self.modules():
            if isinstance(module, nn.Conv2d):
                nn.init.kaiming_normal_(module.weight, mode="fan_out", nonlinearity="relu")

    def forward(self, images: Tensor) -> list[Tensor]:
        """images (B, 3, H, W) -> feature maps [(B, out_channels[i], H / strides[i], W / strides[i])]."""
        x = self.stem(images)
        features = []
        for index, stage in enumerate(self.stages):
            x = stage(x)
            if index in self.out_stages:
                features.append(x)
            if index == self.out_stages[-1]:
                break
        return features


def load_torchvision_weights(resnet: ResNet, path: str | Path) -> None:
    """Load a ResNet state dict saved in torchvision's key layout (e.g. ImageNet weights the
    user downloaded: ``torch.save(torchvision.models.resnet50(weights=...).state_dict(), path)``)
    into ``resnet``. Nothing is downloaded.

    torchvision -> lanelab: ``conv1`` / ``bn1`` -> ``stem.0.0`` / ``stem.0.1``;
    ``layer{k}.{b}.conv{i}`` / ``bn{i}`` -> ``stages.{k-1}.{b}.conv{i}.0`` / ``.1``;
    ``layer{k}.{b}.downsample.{0,1}`` -> ``stages.{k-1}.{b}.shortcut.{0,1}``; ``fc.*`` is ignored.
    The file holds the state dict itself or a checkpoint dict with it under "state_dict" or "model".
    Every parameter and batch-norm buffer of ``resnet`` must come from the file with its shape
    (so depth and width must match: torchvision's ResNets have base width 64); a ValueError
    naming the file and the keys says what does not fit.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such backbone weights file")
    try:
        loaded = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # a truncated or foreign file: say which
        raise ValueError(f"{path}: not a PyTorch state dict ({error})") from error
    for wrapper in ("state_dict", "model"):  # a training checkpoint holding the weights
        if isinstance(loaded, dict) and isinstance(loaded.get(wrapper), dict):
            loaded = loaded[wrapper]
    if not isinstance(loaded, dict):
        raise ValueError(f"{path}: holds a {type(loaded).__name__}, not a state dict")
    origin = {_lanelab_name(key): key for key in loaded if not key.startswith("fc.")}
    renamed = {name: loaded[key] for name, key in origin.items()}
    expected = resnet.state_dict()
    missing = sorted(set(expected) - set(renamed))  # our names: the file lacks them
    unexpected = sorted(origin[k] for k in set(renamed) - set(expected))  # the file's names
    mismatched = sorted(origin[k] for k in set(expected) & set(renamed) if renamed[k].shape != expected[k].shape)
    if missing or unexpected or mismatched:
        problems = [f"{name}: {', '.join(keys[:5])}{' ...' if len(keys) > 5 else ''}"
                    for name, keys in (("missing", missing), ("unexpected", unexpected), ("wrong shape", mismatched)) if keys]  # fmt: skip
        raise ValueError(
            f"{path}: not a torchvision ResNet-{resnet.depth} at base width {resnet.base_width} ({'; '.join(problems)})"
        )
    resnet.load_state_dict(renamed)


def _lanelab_name(key: str) -> str:
    """A torchvision ResNet state-dict key -> the same tensor's key in :class:`ResNet`."""
    parts = key.split(".")
    if parts[0] in ("conv1", "bn1"):
        return ".".join(["stem", "0", "0" if parts[0] == "conv1" else "1", *parts[1:]])
    if parts[0].startswith("layer") and len(parts) >= 4:
        stage, block, module = int(parts[0][5:]) - 1, parts[1], parts[2]
        if module == "downsample":
            return ".".join(["stages", str(stage), block, "shortcut", *parts[3:]])
        if module[:-1] in ("conv", "bn"):
            inner = "0" if module.startswith("conv") else "1"
            return ".".join(["stages", str(stage), block, f"conv{module[-1]}", inner, *parts[3:]])
    return key  # left as it is: reported as unexpected
