"""Pieces shared by the adapters of public datasets (``lanelab-openlane``, ``lanelab-once``), which
make a clip of each folder of label files and the images beside them.

- :func:`read_image_file`: a frame's image as the store keeps it (the bytes as they are), checked
  by decoding it once, so that bytes cut short or corrupt never become a frame;
- :func:`labeled_record`: a labeled frame's store record, with that image;
- :func:`fingerprint`: the sha256 by which a re-run knows a folder's clip is unchanged.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from lanelab.json_files import LaneFileError
from lanelab.lanes import Lane
from lanelab.store import FrameRecord
from lanelab.store.image_codec import compressed_format, compressed_size, decode_compressed


def read_image_file(path: Path, frame: str) -> tuple[bytes, str, int, int]:
    """(bytes, encoding "jpeg" | "png", width, height) of a JPEG or PNG image file; ``frame`` names
    the frame that wants it in the error. LaneFileError names the file when it is missing, not a
    JPEG or PNG, cut short or corrupt."""
    if not path.is_file():
        raise LaneFileError(path, f"no such image ({frame})")
    image = path.read_bytes()
    encoding = compressed_format(image)
    if encoding is None:
        raise LaneFileError(path, "not a JPEG or PNG image")
    try:
        width, height = compressed_size(image, encoding)
        decode_compressed(image, encoding, width, height)
    except ValueError as err:
        raise LaneFileError(path, str(err)) from None
    return image, encoding, width, height


def labeled_record(
    image_path: Path,
    frame: str,
    timestamp_ns: int,
    K: np.ndarray,
    T_lane_cam: np.ndarray,
    T_world_lane: np.ndarray,
    lanes: list[Lane],
    tags: dict[str, str],
) -> FrameRecord:
    """The store record of a labeled frame, its image read from ``image_path`` (:func:`read_image_file`,
    ``frame`` naming the frame in its error)."""
    image, encoding, width, height = read_image_file(image_path, frame)
    return FrameRecord(timestamp_ns=timestamp_ns, image=image, image_encoding=encoding, width=width, height=height,
                       K=K, T_lane_cam=T_lane_cam, T_world_lane=T_world_lane, labeled=True, lanes=lanes, tags=tags)


def fingerprint(paths: Sequence[Path], extra: Any) -> str:
    """sha256 of label files (names and bytes) and of ``extra`` (JSON-able: the tags and options
    that shape the folder's clip)."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    digest.update(json.dumps(extra, sort_keys=True).encode())
    return digest.hexdigest()
