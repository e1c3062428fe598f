"""Crop and resize an image with its intrinsics kept exactly consistent; normalise images for a model.

Pixel coordinates follow :mod:`lanelab.geometry.camera`: pixel (i, j) covers [i, i + 1) x
[j, j + 1). In that convention cropping at (left, top) shifts coordinates by (-left, -top) and
resizing by (sx, sy) scales them, u' = sx (u - left), with no half-pixel terms; ``cv2.resize``
maps pixel centres the same way. So K' = diag(sx, sy, 1) @ [[1, 0, -left], [0, 1, -top],
[0, 0, 1]] @ K, and a 3D point projects onto the same image content before and after.
"""

from __future__ import annotations

from dataclasses import dataclass

from collections.abc import Sequence

import cv2
import numpy as np
import torch
from torch import Tensor


@dataclass(frozen=True)
class ResizeCrop:
    """Cut ``crop`` = (top, left, height, width) source pixels out of an image (None: all of it),
    then resize that to (height, width)."""

    height: int
    width: int
    crop: tuple[int, int, int, int] | None = None

    def box(self, source_height: int, source_width: int) -> tuple[int, int, int, int]:
        """The crop box (top, left, height, width) for a source image of this size."""
        if self.crop is None:
            return 0, 0, source_height, source_width
        top, left, height, width = self.crop
        if not (0 <= top < top + height <= source_height and 0 <= left < left + width <= source_width):
            raise ValueError(f"crop box {self.crop} does not fit a {source_height}x{source_width} image")
        return top, left, height, width

    def intrinsics(self, K: np.ndarray, source_height: int, source_width: int) -> np.ndarray:
        """K (3, 3) of the source image -> K (3, 3) of the output image."""
        top, left, height, width = self.box(source_height, source_width)
        shift = np.array([[1.0, 0.0, -left], [0.0, 1.0, -top], [0.0, 0.0, 1.0]])
        scale = np.diag([self.width / width, self.height / height, 1.0])
        return scale @ shift @ K

    def __call__(self, image: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """image (H0, W0, C) and K (3, 3) -> image (height, width, C) and K (3, 3)."""
        K = self.intrinsics(K, *image.shape[:2])
        top, left, height, width = self.box(*image.shape[:2])
        image = image[top : top + height, left : left + width]
        if (height, width) != (self.height, self.width):
            # Area averaging does not alias when shrinking; bilinear is the usual choice otherwise.
            shrink = self.height < height or self.width < width
            interpolation = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
            image = cv2.resize(image, (self.width, self.height), interpolation=interpolation)
        return np.ascontiguousarray(image), K


class Normalise:
    """uint8 RGB images (F, H, W, 3) -> float32 (F, 3, H, W), normalised with ``mean`` and ``std``
    (per channel, for RGB in [0, 1])."""

    def __init__(self, mean: Sequence[float], std: Sequence[float]) -> None:
        # Images arrive as 0..255.
        self.mean = 255.0 * torch.tensor(mean, dtype=torch.float32).view(3, 1, 1)
        self.std = 255.0 * torch.tensor(std, dtype=torch.float32).view(3, 1, 1)

    def __call__(self, images: np.ndarray) -> Tensor:
        # Channels first while still uint8 (4x fewer bytes to move), then normalise in place.
        images = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).contiguous().float()
        return images.sub_(self.mean).div_(self.std)
