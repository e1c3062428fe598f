"""Images of the clip store: every encoding decodes to RGB; sizes come from the headers."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from lanelab.store import FrameRecord
from lanelab.store.image_codec import compressed_size, decode_image

# A smooth picture (JPEG keeps it close), distinct in every channel.
RGB = np.stack(np.broadcast_arrays(np.arange(8)[None, :] * 30, np.arange(6)[:, None] * 40, 90), axis=-1)
RGB = RGB.astype(np.uint8)


def encoded(encoding: str) -> FrameRecord:
    bgr = np.ascontiguousarray(RGB[..., ::-1])
    data = {"jpeg": lambda: cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes(),
            "png": lambda: cv2.imencode(".png", bgr)[1].tobytes(),
            "rgb8": RGB.tobytes, "bgr8": bgr.tobytes,
            "mono8": lambda: RGB[..., 0].tobytes()}[encoding]()
    return FrameRecord(0, data, encoding, 8, 6, np.eye(3), np.eye(4), np.eye(4), False)


@pytest.mark.parametrize("encoding", ["jpeg", "png", "rgb8", "bgr8", "mono8"])
def test_decode_image_gives_rgb(encoding):
    image = decode_image(encoded(encoding))
    assert image.shape == (6, 8, 3) and image.dtype == np.uint8
    expected = np.repeat(RGB[..., :1], 3, axis=2) if encoding == "mono8" else RGB
    # JPEG is lossy on so small a picture; a swap of channels would be off by 100 or more.
    assert np.abs(image.astype(int) - expected).max() <= (30 if encoding == "jpeg" else 0)
    if encoding in ("jpeg", "png"):
        assert compressed_size(encoded(encoding).image, encoding) == (8, 6)


def test_decode_image_names_unknown_encodings_and_wrong_sizes():
    with pytest.raises(ValueError, match="unknown image encoding 'yuv422'"):
        decode_image(FrameRecord(0, b"\0" * 96, "yuv422", 8, 6, np.eye(3), np.eye(4), np.eye(4), False))
    with pytest.raises(ValueError, match="needs 144 bytes"):
        decode_image(FrameRecord(0, b"\0" * 96, "rgb8", 8, 6, np.eye(3), np.eye(4), np.eye(4), False))
