"""Photometric augmentation of the frames of one sample, with one set of parameters for all.

Drawing the jitter once per sample (not per frame) keeps the window temporally consistent: a
model comparing frames sees the scene change, not the augmentation. Geometry is untouched, so
intrinsics and labels stay valid. Validation and test loaders use none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch

# Luma weights (ITU-R BT.601), as torchvision's grayscale; they sum to 1.
_LUMA = np.array([0.299, 0.587, 0.114])
# RGB -> YIQ: a hue shift is a rotation of the (I, Q) chroma plane, one 3x3 matrix in RGB.
_RGB_TO_YIQ = np.array([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])


@dataclass(frozen=True)
class PhotometricAugment:
    """Brightness, contrast, saturation and hue jitter, then optional Gaussian noise.

    Factors are drawn uniformly from [1 - a, 1 + a] for brightness, contrast and saturation (a
    the given amount), the hue shift from [-hue, hue] turns of the colour wheel; noise has
    standard deviation ``noise_std`` (as a fraction of the full range) and is drawn per pixel
    and frame, as sensor noise is. Random numbers come from torch's generator, which
    DataLoader seeds per worker.
    """

    brightness: float = 0.0
    contrast: float = 0.0
    saturation: float = 0.0
    hue: float = 0.0
    noise_std: float = 0.0

    def __call__(self, images: np.ndarray, generator: torch.Generator | None = None) -> np.ndarray:
        """images (F, H, W, 3) uint8 RGB -> augmented, same shape and dtype."""
        def uniform(amount: float) -> float:  # in [-amount, amount]
            return amount * (2.0 * torch.rand((), generator=generator).item() - 1.0)

        brightness, contrast = 1.0 + uniform(self.brightness), 1.0 + uniform(self.contrast)
        saturation, hue = 1.0 + uniform(self.saturation), uniform(self.hue)

        # All four are linear in RGB: scale by brightness; blend with the frame's mean luma by
        # contrast; blend with the pixel's luma by saturation; rotate hue. Together one affine
        # map A x + (1 - contrast) * mean, as saturation and hue leave grey unchanged; OpenCV
        # applies it in one pass and saturates to [0, 255].
        desaturate = saturation * np.eye(3) + (1.0 - saturation) * _LUMA
        A = brightness * contrast * _hue_rotation(hue) @ desaturate
        out = np.empty_like(images)
        for frame, image in enumerate(images):
            mean = brightness * (_LUMA @ cv2.mean(image)[:3])
            out[frame] = cv2.transform(image, np.hstack([A, np.full((3, 1), (1.0 - contrast) * mean)]))
        if self.noise_std > 0:
            noise = torch.randn(out.shape, generator=generator).numpy() * (255.0 * self.noise_std)
            out = np.clip(out + noise, 0, 255).round().astype(np.uint8)
        return out


def _hue_rotation(turns: float) -> np.ndarray:
    """(3, 3) RGB matrix rotating hue by ``turns`` of the colour wheel about the grey axis.

    A rotation of YIQ's chroma plane: cheaper than an HSV round trip and linear, though not
    identical to HSV's hue.
    """
    angle = 2.0 * math.pi * turns
    cos, sin = math.cos(angle), math.sin(angle)
    rotate = np.array([[1.0, 0.0, 0.0], [0.0, cos, -sin], [0.0, sin, cos]])
    return np.linalg.inv(_RGB_TO_YIQ) @ rotate @ _RGB_TO_YIQ
