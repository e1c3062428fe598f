"""Photometric augmentation: one draw per sample, identity when off, grey stays grey."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lanelab.data.augment import PhotometricAugment


def frames(num_frames=3, seed=0, low=0, high=256) -> np.ndarray:
    """(F, H, W, 3) uint8 RGB noise."""
    return np.random.default_rng(seed).integers(low, high, (num_frames, 16, 20, 3), dtype=np.uint8)


def generator(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_off_is_identity():
    images = frames()
    np.testing.assert_array_equal(PhotometricAugment()(images), images)


def test_the_same_jitter_for_every_frame_of_a_sample():
    augment = PhotometricAugment(brightness=0.3, contrast=0.3, saturation=0.3, hue=0.05)
    same = np.repeat(frames(1), 4, axis=0)
    out = augment(same, generator(1))
    assert out.shape == same.shape and out.dtype == np.uint8
    for frame in out[1:]:
        np.testing.assert_array_equal(frame, out[0])
    assert np.abs(out[0].astype(int) - same[0]).mean() > 1


def test_brightness_alone_scales_within_its_range():
    images = frames(low=64, high=200)
    for seed in range(5):
        out = PhotometricAugment(brightness=0.2)(images, generator(seed)).astype(float)
        factor = np.median(out / images)
        assert 0.8 <= factor <= 1.2
        np.testing.assert_allclose(out, np.clip(np.round(images * factor), 0, 255), atol=1.0)


@pytest.mark.parametrize("kind", ["saturation", "hue"])
def test_grey_stays_grey(kind):
    grey = np.repeat(np.linspace(20, 230, 5).astype(np.uint8), 16 * 20 * 3).reshape(5, 16, 20, 3)
    out = PhotometricAugment(**{kind: 0.5})(grey, generator(0))
    np.testing.assert_allclose(out, grey, atol=1)


def test_contrast_keeps_each_frames_mean():
    images = frames(low=50, high=200)
    out = PhotometricAugment(contrast=0.5)(images, generator(2)).astype(float)
    np.testing.assert_allclose(out.mean(axis=(1, 2, 3)), images.mean(axis=(1, 2, 3)), atol=0.6)
    assert out.std() != pytest.approx(images.std(), rel=0.01)


def test_deterministic_for_a_generator_and_saturating():
    augment = PhotometricAugment(brightness=0.9, contrast=0.9, saturation=0.9, hue=0.5, noise_std=0.1)
    a = augment(frames(), generator(3))
    np.testing.assert_array_equal(a, augment(frames(), generator(3)))
    assert a.dtype == np.uint8 and a.shape == frames().shape
