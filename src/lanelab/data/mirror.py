"""Left-right mirroring of a sample: images, cameras, ego poses and lanes alike.

A mirror image of a road is another valid road (a left curve becomes a right one, a lane on
the left one on the right), so mirroring doubles the layouts a model sees. The world is
reflected in the plane x = 0 of the lane frame (x right): a point p becomes S p with
S = diag(-1, 1, 1), and every frame along with it, so every transform T becomes S T S (the
camera frame's x, right in the image, flips too). The pinhole model then needs only the
principal point moved, cx -> W - cx (pixel-area convention, :mod:`lanelab.geometry.camera`:
pixel column u becomes W - u), and the skew negated. Lane categories with a side swap it.
"""

from __future__ import annotations

import numpy as np

# OpenLane ids (DESIGN.md, "Lane categories") that name a side, and their mirror images.
MIRRORED_CATEGORIES = {5: 6, 6: 5, 11: 12, 12: 11, 20: 21, 21: 20}
_S = np.diag([-1.0, 1.0, 1.0, 1.0])


def mirror_transforms(T: np.ndarray) -> np.ndarray:
    """Transforms (..., 4, 4) between frames of the reflected world: S T S."""
    return _S @ T @ _S


def mirror_intrinsics(K: np.ndarray, width: int) -> np.ndarray:
    """K (..., 3, 3) of images width pixels wide -> K of the images flipped left to right."""
    K = np.array(K, dtype=np.float64, copy=True)
    K[..., 0, 2] = width - K[..., 0, 2]
    K[..., 0, 1] = -K[..., 0, 1]
    return K


def mirror_categories(categories: np.ndarray) -> np.ndarray:
    """OpenLane category ids (any shape) with left and right swapped."""
    return np.vectorize(lambda c: MIRRORED_CATEGORIES.get(int(c), int(c)), otypes=[np.int64])(categories)
