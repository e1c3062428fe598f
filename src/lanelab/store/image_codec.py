"""Images of the clip store: which encodings exist, their sizes, and decoding to RGB.

A clip stores each image's bytes as they came from the drive log (DESIGN.md, "Clip store
contract"): ``jpeg`` and ``png`` files, or raw rows of ``rgb8``, ``bgr8`` or ``mono8``
pixels (``height * width * channels`` bytes, no row padding).
"""

from __future__ import annotations

import struct
from typing import Protocol

import cv2
import numpy as np

COMPRESSED_ENCODINGS = ("jpeg", "png")
RAW_CHANNELS = {"rgb8": 3, "bgr8": 3, "mono8": 1}
IMAGE_ENCODINGS = COMPRESSED_ENCODINGS + tuple(RAW_CHANNELS)

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_JPEG_MAGIC = b"\xff\xd8"
# JPEG start-of-frame markers (baseline, progressive, lossless, ...): they hold the size.
# 0xC4 (Huffman tables), 0xC8 (reserved) and 0xCC (arithmetic coding) are not frames.
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# The end of an image: JPEG's EOI marker, PNG's IEND chunk (type and CRC), searched for in the last bytes.
_JPEG_END, _PNG_END, _END_SEARCH = b"\xff\xd9", b"IEND\xaeB`\x82", 64
# Markers without a length field: TEM, RST0-7, SOI, EOI.
_JPEG_STANDALONE = frozenset([0x01, *range(0xD0, 0xDA)])


class EncodedImage(Protocol):
    """What :func:`decode_image` needs (a :class:`~lanelab.store.records.FrameRecord` has it)."""

    image: bytes
    image_encoding: str
    width: int
    height: int


def compressed_format(data: bytes) -> str | None:
    """"jpeg" or "png" from the file's magic bytes; None for anything else."""
    if data.startswith(_JPEG_MAGIC):
        return "jpeg"
    if data.startswith(_PNG_MAGIC):
        return "png"
    return None


def compressed_size(data: bytes, encoding: str) -> tuple[int, int]:
    """(width, height) read from a JPEG or PNG header, without decoding the pixels."""
    if encoding == "png":
        if len(data) < 24:
            raise ValueError("PNG data ends before its IHDR header")
        return struct.unpack(">II", data[16:24])
    if encoding != "jpeg":
        raise ValueError(f"not a compressed image encoding: {encoding!r} (one of {', '.join(COMPRESSED_ENCODINGS)})")
    i = 2  # after SOI
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            raise ValueError(f"JPEG data has no marker at byte {i}")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in _JPEG_STANDALONE:
            i += 2
            continue
        if marker in _JPEG_SOF:
            if i + 9 > len(data):
                break
            height, width = struct.unpack(">HH", data[i + 5:i + 9])
            return width, height
        (length,) = struct.unpack(">H", data[i + 2:i + 4])
        i += 2 + length
    raise ValueError("JPEG data has no start-of-frame header")


def decode_compressed(data: bytes, encoding: str, width: int, height: int) -> np.ndarray:
    """JPEG or PNG bytes of a ``width`` x ``height`` image -> (H, W, 3) uint8 BGR.

    Raises ValueError saying what is wrong with the bytes: cut short (a header that promises
    more than the data holds) or corrupt, or an image of another size.
    """
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)  # gray or 16-bit PNGs: 8-bit BGR
    if bgr is None:
        end = _JPEG_END if encoding == "jpeg" else _PNG_END
        if end not in data[-_END_SEARCH:]:  # encoders may pad after the end marker, not much
            raise ValueError(f"the bytes stop before the image's end ({encoding} data cut short)")
        raise ValueError(f"the bytes hold corrupt {encoding} data that cannot be decoded")
    if bgr.shape[:2] != (height, width):
        raise ValueError(f"{encoding} image decodes to {bgr.shape[1]}x{bgr.shape[0]}, its header or frame says "
                         f"{width}x{height}")
    return bgr


def decode_image(frame: EncodedImage) -> np.ndarray:
    """A stored image -> (H, W, 3) uint8 RGB, whatever its ``image_encoding``.

    Raises ValueError on an unknown encoding or bytes that do not make a
    ``height`` x ``width`` image.
    """
    encoding, width, height = frame.image_encoding, frame.width, frame.height
    if encoding in COMPRESSED_ENCODINGS:
        return cv2.cvtColor(decode_compressed(frame.image, encoding, width, height), cv2.COLOR_BGR2RGB)
    data = np.frombuffer(frame.image, dtype=np.uint8)
    if encoding not in RAW_CHANNELS:
        raise ValueError(f"unknown image encoding {encoding!r}; known: {', '.join(IMAGE_ENCODINGS)}")
    channels = RAW_CHANNELS[encoding]
    if data.size != height * width * channels:
        raise ValueError(f"{encoding} image of {width}x{height} needs {height * width * channels} bytes, "
                         f"got {data.size}")
    pixels = data.reshape(height, width, channels)
    if encoding == "rgb8":
        return pixels.copy()  # a writable array, not a view of the bytes
    if encoding == "bgr8":
        return np.ascontiguousarray(pixels[..., ::-1])
    return np.repeat(pixels, 3, axis=2)
