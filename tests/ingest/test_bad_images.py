"""Issue 37, case 2: an image whose bytes are cut short behind a valid header, or are not an
image at all, never becomes a good frame; the reason says what is wrong with the bytes."""

from __future__ import annotations

import base64
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from ingest_helpers import ingest_into, read_log, write_log

from lanelab.store import ClipStore
from lanelab.store.image_codec import decode_compressed, decode_image

IMAGE = "/camera/front/image"
CUT_SHORT = "image message unusable: garbled jpeg image: the bytes stop before the image's end (jpeg data cut short)"
GARBAGE = ("image message unusable: format 'jpeg', but the bytes are neither JPEG nor PNG (no signature at their "
           "start: garbage data)")


def with_image_bytes(log: Path, out: Path, spoil: dict[int, callable]) -> Path:
    """The log with the bytes of image k replaced by ``spoil[k](bytes)`` (Foxglove JSON: base64)."""
    messages, k = [], 0
    for m in read_log(log):
        if m.topic == IMAGE:
            if k in spoil:
                image = json.loads(m.data)
                image["data"] = base64.b64encode(spoil[k](base64.b64decode(image["data"]))).decode()
                m = dataclasses.replace(m, data=json.dumps(image).encode())
            k += 1
        messages.append(m)
    return write_log(out, messages)


def test_a_truncated_jpeg_and_garbage_bytes_are_dropped_with_what_is_wrong(tmp_path, synth_log):
    def cut(data: bytes) -> bytes:
        return data[: len(data) * 2 // 3]  # the header (size and tables) stays valid

    def garbage(data: bytes) -> bytes:
        return np.random.default_rng(0).bytes(len(data))

    log = with_image_bytes(synth_log("foxglove-json"), tmp_path / "images.mcap", {2: cut, 3: cut, 9: garbage})
    (result,) = ingest_into(tmp_path / "store", log)
    assert result.status == "ingested" and result.num_frames == 17
    assert result.dropped == {CUT_SHORT: 2, GARBAGE: 1}
    store = ClipStore(tmp_path / "store")
    for clip in store.clips:
        for frame in store.read_frames(clip.clip_id):
            assert decode_image(frame).shape == (frame.height, frame.width, 3)  # every stored image decodes


def test_corrupt_data_and_another_size_are_named(synth_log):
    image = json.loads(next(m for m in read_log(synth_log("foxglove-json")) if m.topic == IMAGE).data)
    data = base64.b64decode(image["data"])
    assert decode_compressed(data, "jpeg", 160, 120).shape == (120, 160, 3)
    with pytest.raises(ValueError, match="decodes to 160x120, its header or frame says 320x240"):
        decode_compressed(data, "jpeg", 320, 240)
    corrupt = data[:20] + b"\x00" * (len(data) - 22) + data[-2:]  # the end marker kept
    with pytest.raises(ValueError, match="the bytes hold corrupt jpeg data that cannot be decoded"):
        decode_compressed(corrupt, "jpeg", 160, 120)
